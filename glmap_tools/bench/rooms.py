"""Does the scorer f_S point at the goal's room? Scores every unit text of a scene, no agent.

`python -m glmap_tools.bench rooms [--split tune] [--task objectnav] [--scorer embedding|llm]`

Eq. 7 steers the agent into the right room only if units in the goal's room outscore units
elsewhere. For each episode, every region description and every object description of its
scene (the goal objects themselves left out) is scored against the goal text, as the map's
units would be once seen. Printed per unit kind:

- room ranking: the share of episodes whose best unit in the goal's room (a room holding a
  goal object) scores above the best unit in every other room (a tie counts as a miss),
  next to what random scores would give (the goal room's share of the units);
- for thresholds t: the share of episodes with some unit at or above t in the goal's room,
  and in another room (what a score floor on the units would keep; nav/design.md).

Ground truth comes from the layout files, so this reads no images and runs in seconds with
the embedding scorer; `--scorer llm` asks the Ollama model (the scene's regions and objects in
batches, for each goal). Use the tune split for choices; the bench split is for final figures only.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from glmap_tools.bench._nav_loop import embedder as bundled
from glmap_tools.bench.report import Report
from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.language.backends import add_llm_arguments, make_scorer, settings_from_args
from glmap_tools.nav.scorers import UnitText
from glmap_tools.worlds.splits import bench_layout, load_split

THRESHOLDS = (0.2, 0.3, 0.4, 0.5)
ROOM_RANKING_TARGET = 0.8


@dataclass(frozen=True)
class RoomScores:
    """The best score of one unit kind inside and outside the goal's room, for one episode.

    Attributes:
        same: best score among units in a room that holds a goal object (0 when none).
        other: best score among units in every other room (0 when none).
        chance: the share of the units that lie in the goal's room: how often its best unit
            would rank first if scores were drawn at random.
    """

    same: float
    other: float
    chance: float = 0.0


def episode_room_scores(
    scorer: Any, goal: str, layout: Any, goal_object_ids: Sequence[int]
) -> dict[str, RoomScores]:
    """{'region': ..., 'instance': ...}: best scores in and out of the goal's room.

    Args:
        scorer: a `glmap_tools.nav.Scorer`.
        goal: the goal text.
        layout: the scene (`glmap_tools.sim.layout.Layout`).
        goal_object_ids: the goal objects; they are not scored (finding them is the stop
            rule's job, not the value map's).
    """
    goal_ids = set(goal_object_ids)
    rooms = {o.room for o in layout.objects if o.id in goal_ids}
    if not rooms:
        raise InvalidInputError(
            f"goal objects {sorted(goal_ids)} are not in layout {layout.name!r}; "
            "regenerate the split (python -m glmap_tools.worlds.splits)."
        )
    out: dict[str, RoomScores] = {}
    kinds = {
        "region": [(r.room, r.description) for r in layout.regions if r.description],
        "instance": [
            (o.room, o.description)
            for o in layout.objects
            if o.id not in goal_ids and o.description
        ],
    }
    for kind, items in kinds.items():
        units = [UnitText(k, kind, text) for k, (_, text) in enumerate(items)]
        scores = np.asarray(scorer.score(goal, units), dtype=float) if units else np.zeros(0)
        inside = np.array([room in rooms for room, _ in items], dtype=bool)
        out[kind] = RoomScores(
            float(scores[inside].max(initial=0.0)),
            float(scores[~inside].max(initial=0.0)),
            float(inside.mean()) if len(items) else 0.0,
        )
    return out


def room_table(rows: Sequence[dict[str, RoomScores]], report: Report) -> dict[str, float]:
    """Print the room ranking and threshold shares per kind; return the ranking per kind."""
    ranking: dict[str, float] = {}
    for kind in ("region", "instance"):
        same = np.array([r[kind].same for r in rows])
        other = np.array([r[kind].other for r in rows])
        ranking[kind] = float((same > other).mean())
        report.check(
            f"{kind} units: goal's room ranked first, {len(rows)} episodes",
            ranking[kind],
            ">=",
            ROOM_RANKING_TARGET,
        )
        chance = float(np.mean([r[kind].chance for r in rows]))
        report.info(
            f"  {kind}: {chance:.2f} by chance (the goal room's share of the units); mean best "
            f"score in the goal's room {same.mean():.3f}, elsewhere {other.mean():.3f}"
        )
        for t in THRESHOLDS:
            report.info(
                f"  {kind} score >= {t:.1f}: goal's room {(same >= t).mean():.2f} of episodes, "
                f"another room {(other >= t).mean():.2f}"
            )
    return ranking


def main(argv: list[str] | None = None) -> int:

    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench rooms")
    parser.add_argument("--split", default="tune", choices=("tune", "bench"))
    parser.add_argument("--task", default="objectnav", choices=("objectnav", "instnav"))
    add_llm_arguments(parser)
    args = parser.parse_args(argv)
    settings = settings_from_args(args)
    embedder = None
    if settings.scorer == "embedding":
        embedder = bundled()
    scorer = make_scorer(settings, embedder)
    report = Report(f"bench rooms ({args.split} {args.task}, scorer {settings.scorer})")
    layouts: dict[Any, Any] = {}
    cache: dict[tuple[Any, str, tuple[int, ...]], dict[str, RoomScores]] = {}
    rows = []
    try:
        for be in load_split(args.split, args.task):
            if be.layout_path not in layouts:
                layouts[be.layout_path] = bench_layout(be.layout_path)
            key = (be.layout_path, be.episode.goal_text, tuple(be.episode.goal_object_ids))
            if key not in cache:
                cache[key] = episode_room_scores(
                    scorer, be.episode.goal_text, layouts[be.layout_path], key[2]
                )
            rows.append(cache[key])
    except GLMapError as error:  # no model server, a stale split: say so, no traceback
        print(f"bench rooms: {error}", file=sys.stderr)
        return 2
    report.info(f"{len(rows)} episodes, {len(layouts)} scenes, {len(cache)} scored goals")
    room_table(rows, report)
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
