"""f_S from the client: region scores an eval agent gives `value_map` (paper Eq. 7's s_u).

The agents `glmap+oracle-room`, `glmap+wrong-room`, `glmap+embedding` and `glmap+recorded` play
the glmap policy
through `nav_step` and, whenever the map holds regions they have not scored, read the
region and instance index (the `glmap://current/...` resources) and send the new scores
with `value_map(scores=...)`, as a user's LLM client would. They score *regions* only: a
client-scored instance is a goal match at the stop threshold (`nav.scorers.ClientScorer`),
so instances keep the server's scorer and every variant stops by the same rule; what
differs is where the value map sends the agent.

- `oracle-room` (an upper bound, not an agent): 1 for a region whose members stand, on
  average, in a room of a kind that holds a goal object (the scene's ground truth), else 0.
- `wrong-room` (a lower bound, not an agent): the oracle turned round, 1 for a region in a
  room of a kind that holds no goal object, else 0: a prior wrong everywhere, which shows
  whether the value map follows f_S at all.
- `embedding`: the server's own f_S computed in the client (MiniLM cosine of the goal's
  noun phrase and the region text, `(cos - 0.2) / 0.8`): the channel's null check.
- `recorded`: scores a model gave earlier, from a JSONL file of
  `{"goal", "text", "score"}` lines (`GLMAP_FS_RECORDED`); a text with no line is left to
  the server's scorer.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from glmap_tools.errors import InvalidInputError

# Imports inside functions stay there: the split's layouts (gymnasium), nav's scorer and the
# MiniLM embedder load only for the scorers that read them (oracle-room, embedding), not
# for a client playing with recorded scores or none.

FS_SOURCES = ("oracle-room", "wrong-room", "embedding", "recorded")
RECORDED_ENV = "GLMAP_FS_RECORDED"


@dataclass(frozen=True)
class RegionView:
    """A region as the client reads it from the map's index.

    Attributes:
        region_id: the region unit's id.
        text: its description.
        xy: the mean (x, y) of its member instances' centroids, metres (None without members).
    """

    region_id: int
    text: str
    xy: tuple[float, float] | None


class RegionScorer(Protocol):
    def score(self, goal: str, regions: Sequence[RegionView]) -> dict[int, float]:
        """Region id -> s_u in [0, 1] for the regions it has an opinion on."""
        ...


def region_views(
    regions: Sequence[Mapping[str, Any]], instances: Sequence[Mapping[str, Any]]
) -> list[RegionView]:
    """RegionViews from the `glmap://current/regions` and `.../instances` index JSON."""
    centroid = {int(i["id"]): i["centroid"] for i in instances}
    out = []
    for r in regions:
        pts = [centroid[m][:2] for m in r.get("instance_ids", []) if m in centroid]
        xy = tuple(float(v) for v in np.mean(pts, axis=0)) if pts else None
        out.append(RegionView(int(r["id"]), str(r["description"]), xy))  # type: ignore[arg-type]
    return out


@dataclass
class OracleRoom:
    """1 for regions in a room of the goal's kind (the scene's ground truth), else 0.

    Args:
        rooms: (room kind, [K, 2] polygon) of every room of the scene.
        goal_kinds: the kinds of the rooms that hold a goal object.
        wrong: score the other way round (1 outside the goal's kinds of room, inside 0).
    """

    rooms: list[tuple[str, np.ndarray]]
    goal_kinds: frozenset[str]
    wrong: bool = False

    @classmethod
    def for_episode(cls, episode_id: str, wrong: bool = False) -> OracleRoom:
        # glmap_tools.sim loads gymnasium: only the oracle needs it, not the runner's start.
        from glmap_tools.worlds.splits import bench_episode, bench_layout

        be = bench_episode(episode_id)
        layout = bench_layout(be.layout_path)
        kind = {room.id: room.type for room in layout.rooms}
        goal_ids = set(be.episode.goal_object_ids)
        kinds = frozenset(
            kind[o.room] for o in layout.objects if o.id in goal_ids and o.room in kind
        )
        return cls([(room.type, room.polygon) for room in layout.rooms], kinds, wrong)

    def room_kind(self, xy: tuple[float, float]) -> str | None:
        from glmap_tools.sim.layout import points_in_polygon

        for kind, polygon in self.rooms:
            if bool(points_in_polygon(np.array([xy]), polygon)[0]):
                return kind
        return None

    def score(self, goal: str, regions: Sequence[RegionView]) -> dict[int, float]:
        out = {}
        for r in regions:
            kind = self.room_kind(r.xy) if r.xy is not None else None
            goal_kind = kind in self.goal_kinds
            out[r.region_id] = float(kind is not None and goal_kind != self.wrong)
        return out


_EMBEDDING: list[Any] = []  # one EmbeddingScorer per process (the model loads once)


class ClientEmbedding:
    """The server's embedding f_S, computed in the client from the region texts."""

    def score(self, goal: str, regions: Sequence[RegionView]) -> dict[int, float]:
        from glmap_tools.nav.scorers import EmbeddingScorer, UnitText

        if not _EMBEDDING:
            from glmap_tools.language.minilm import default_embedder

            _EMBEDDING.append(EmbeddingScorer(default_embedder()))
        units = [UnitText(r.region_id, "region", r.text) for r in regions]
        if not units:
            return {}
        return {
            u.unit_id: float(s)
            for u, s in zip(units, _EMBEDDING[0].score(goal, units), strict=True)
        }


@dataclass
class Recorded:
    """Scores read from a JSONL file of {"goal", "text", "score"} lines (a model's, earlier).

    Attributes:
        table: (goal, text), each lower-cased and single-spaced, -> score.
        missing: texts asked for that the file has no line for.
    """

    table: dict[tuple[str, str], float]
    missing: set[str] = field(default_factory=set)

    @classmethod
    def from_file(cls, path: str | os.PathLike[str]) -> Recorded:
        table: dict[tuple[str, str], float] = {}
        p = Path(path)
        if not p.is_file():
            raise InvalidInputError(
                f"recorded scores file {str(p)!r} does not exist; set {RECORDED_ENV} to a "
                'JSONL file of {"goal": ..., "text": ..., "score": 0..1} lines.'
            )
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
                score = float(row["score"])
                key = (_norm(row["goal"]), _norm(row["text"]))
            except (ValueError, KeyError, TypeError) as exc:
                raise InvalidInputError(
                    f'{p}:{n} is not a {{"goal", "text", "score"}} line ({exc}).'
                ) from exc
            if not 0.0 <= score <= 1.0:
                raise InvalidInputError(f"{p}:{n}: score {score!r} is not in [0, 1].")
            table[key] = score
        return cls(table)

    def score(self, goal: str, regions: Sequence[RegionView]) -> dict[int, float]:
        out = {}
        for r in regions:
            s = self.table.get((_norm(goal), _norm(r.text)))
            if s is None:
                self.missing.add(r.text)
            else:
                out[r.region_id] = s
        return out


def _norm(text: str) -> str:
    return " ".join(str(text).lower().split())


def split_agent(agent: str) -> tuple[str, str | None]:
    """('glmap', 'oracle-room') for 'glmap+oracle-room'; (agent, None) without a '+'."""
    policy, plus, source = agent.partition("+")
    return (policy, source) if plus else (agent, None)


def region_scorer(source: str, episode_id: str) -> RegionScorer:
    """The scorer of `source` (FS_SOURCES) for one episode."""
    if source in ("oracle-room", "wrong-room"):
        return OracleRoom.for_episode(episode_id, wrong=source == "wrong-room")
    if source == "embedding":
        return ClientEmbedding()
    if source == "recorded":
        path = os.environ.get(RECORDED_ENV, "")
        if not path:
            raise InvalidInputError(
                f"the recorded f_S needs {RECORDED_ENV}=FILE, a JSONL file of "
                '{"goal": ..., "text": ..., "score": 0..1} lines.'
            )
        return Recorded.from_file(path)
    raise InvalidInputError(f"f_S source {source!r} is not one of {list(FS_SOURCES)}.")
