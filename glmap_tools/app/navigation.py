"""`NavSession`: the navigation state of one simulator episode (a `Session`'s `nav`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.nav import NavConfig, NavDecision, NavState, Scorer
    from glmap_tools.nav.scorers import ClientScores
    from glmap_tools.perception.semantics import FrameSemantics


@dataclass
class NavSession:
    """Navigation state of one simulator episode.

    Attributes:
        goal: the episode's goal text.
        state: egocentric accumulator, stuck memory, last waypoint.
        config: the navigation settings of the episode's task.
        scorer: f_S (`glmap_tools.nav.EmbeddingScorer` on the server's embedder, or an LLM's).
        embedder: the text embedder (frame scores of the egocentric baseline).
        path: [(x, y)] agent positions, one per integrated frame.
        decision: the latest `NavDecision` (drawn by value_map), or None.
        client: the client's f_S for the goal (set_goal_scores), or None; sim_reset starts
            a new NavSession, so a new episode starts without them.
    """

    goal: str
    state: NavState
    config: NavConfig
    scorer: Scorer
    embedder: Embedder
    path: list[tuple[float, float]] = field(default_factory=list)
    decision: NavDecision | None = None
    client: ClientScores | None = None
    _text_vecs: dict[str, np.ndarray] = field(default_factory=dict)

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

    def frame_score(self, semantics: FrameSemantics) -> float:
        """What the frame shows scored against the goal (f_S of its best object or group).

        The egocentric (VLFM-like) baseline's per-frame score; text embeddings are cached,
        since the same objects are seen frame after frame.
        """
        from glmap_tools.nav import UnitText

        texts = [o.description or o.label for o in semantics.objects]
        texts = [t for t in texts + [g.description for g in semantics.groups] if t.strip()]
        if not texts:
            return 0.0
        todo = [t for t in dict.fromkeys(texts) if t not in self._text_vecs]
        if todo:
            for t, v in zip(todo, np.asarray(self.embedder.embed(todo)), strict=True):
                self._text_vecs[t] = v
        units = [UnitText(-1, "instance", t, self._text_vecs[t]) for t in texts]
        return float(np.max(self.scorer.score(self.goal, units)))
