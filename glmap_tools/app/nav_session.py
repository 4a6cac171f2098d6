"""`NavSession`: the navigation state of one simulator episode (a `Session`'s `nav`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from glmap_tools.nav import NavConfig, NavDecision, NavState, Scorer
    from glmap_tools.nav.perceive import TextVectors
    from glmap_tools.nav.scorers import ClientScores

# Imports inside functions stay there: gaussians, language.embed, scipy, numba load on first use:
# build_server stays light (test_server_startup): the server loads them in the background or on
# first use; the tools load before these do, in the server and the in-process toolset alike.


@dataclass
class NavSession:
    """Navigation state of one simulator episode.

    Attributes:
        goal: the episode's goal text.
        state: egocentric accumulator, stuck memory, last waypoint.
        config: the navigation settings of the episode's task.
        scorer: f_S (`glmap_tools.nav.EmbeddingScorer` on the server's embedder, or an LLM's).
        texts: embeddings of the texts frames showed (the egocentric baseline's frame
            scores; the same objects are seen frame after frame).
        path: [(x, y)] agent positions, one per integrated frame.
        decision: the latest `NavDecision` (drawn by value_map), or None.
        client: the client's f_S for the goal (set_goal_scores), or None; sim_reset starts
            a new NavSession, so a new episode starts without them.
    """

    goal: str
    state: NavState
    config: NavConfig
    scorer: Scorer
    texts: TextVectors
    path: list[tuple[float, float]] = field(default_factory=list)
    decision: NavDecision | None = None
    client: ClientScores | None = None

    def goal_scorer(self, fused_into: dict[int, int] | None = None) -> Scorer:
        """f_S for the episode: the client's scores over the configured scorer, or the
        configured scorer alone. `fused_into` (the map's): client scores of fused ids move
        to the unit they became."""
        from glmap_tools.nav.scorers import ClientScorer

        if self.client is None or self.client.empty:
            return self.scorer
        if fused_into:
            self.client.follow(fused_into)
        return ClientScorer(self.scorer, self.client, self.config.stop_threshold)
