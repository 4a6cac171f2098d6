"""`python -m glmap_tools.regression.replay`: seeded episodes and tours, recorded field for field.

A refactor that claims "behaviour unchanged" records a run before and after and compares:

    python -m glmap_tools.regression.replay --out before.json          # on the old tree
    python -m glmap_tools.regression.replay --out after.json --compare before.json

Each episode (tune split, simulator seed 0) records every step's action, pose, waypoint,
plan length, matched unit and the frame's update report, and at its end a fingerprint of
the map: every unit's fields with SHA-256 digests of its arrays (embedding, Gaussians),
the index grid, occupancy and structure layer. Each tour (bench scene, `worlds.tour` frames)
records the same fingerprint. Floats are kept as `repr`, so equality means bit-identical.

The simulator's frames can differ in a last bit from run to run on a loaded machine (a few
Gaussians of one instance then differ between two runs of the same code), so a record
compares commits only on a quiet machine. `--against DIR` needs no quiet machine: one
process plays every episode and tour once and feeds each frame to both `plan_frame` and
`decide` of this tree and of the tree at DIR (`against.py`: its `map/fusion.py` and `nav/policy.py`,
loaded beside this tree's modules), comparing the maps, reports, decisions and navigation
states after every step:

    python -m glmap_tools.regression.replay --against /path/to/old/checkout

`--golden` writes the short record the test `tests/test_replay_golden.py` holds the code
to (`tests/data/replay_golden.json`: three episodes' actions and poses, rounded).
"""

from __future__ import annotations

import argparse
import json
import os
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

import glmap_tools.data
from glmap_tools.bench.report import Report
from glmap_tools.language.minilm import default_embedder as embedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav import NavConfig
from glmap_tools.nav.episode import play as play_steps
from glmap_tools.regression.against import play_against, situate_against, tour_against
from glmap_tools.regression.fingerprint import differences, digest, map_fingerprint, report_fields
from glmap_tools.sim.render import CameraSpec
from glmap_tools.worlds.map_eval import build_map_from_tour
from glmap_tools.worlds.splits import bench_layout, load_split, make_env

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

GOLDEN = Path(__file__).resolve().parents[2] / "tests" / "data" / "replay_golden.json"
# (task, tune index, policy): one per policy family, goals seen early.
EPISODES = [
    ("objectnav", 0, "glmap"),
    ("objectnav", 6, "glmap"),
    ("instnav", 2, "glmap"),
    ("objectnav", 4, "egocentric"),
    ("objectnav", 8, "frontier"),
]
GOLDEN_EPISODES = EPISODES[:3]
ACTION_LETTERS = {"stop": "s", "move_forward": "f", "turn_left": "l", "turn_right": "r"}
TOURS = ["s00", "s01"]


def play(task: str, index: int, policy: str, max_steps: int) -> dict[str, Any]:
    """Play one tune episode (`nav.episode.play`); every step's decision and the final
    map's fingerprint."""

    be = load_split("tune", task)[index]
    env = make_env(be, camera=CameraSpec(320, 240), max_steps=max_steps)
    steps: list[dict[str, Any]] = []
    glmap = GLMap(MapConfig(), embedder=embedder())
    config = NavConfig.for_task(be.task)
    try:
        for step in play_steps(env, glmap, policy, config, {"episode": be.episode}):
            d, (x, y, heading) = step.decision, step.agent
            wp = d.waypoint
            steps.append(
                {
                    "pose": [repr(x), repr(y), repr(heading)],
                    "action": d.action,
                    "waypoint": [wp.kind, repr(wp.xy), wp.unit_id, repr(wp.score), wp.reason],
                    "plan": [repr(d.plan.length), d.plan.reachable, len(d.plan.path)],
                    "matched": d.matched_unit,
                    "frontiers": len(d.frontiers),
                    "scores": digest(np.array(sorted(d.scores.items()), dtype=float)),
                    "report": report_fields(step.report),
                }
            )
            info = step.info
    finally:
        env.close()
    return {
        "episode": f"{task}/{index}/{policy}",
        "success": bool(info["success"]),
        "spl": repr(float(info["spl"])),
        "steps": steps,
        "map": map_fingerprint(glmap),
    }


def tour(scene: str, max_frames: int) -> dict[str, Any]:
    """Build a map from a bench scene's tour; its fingerprint."""

    layout = Path(glmap_tools.data.__path__[0]) / "benchmark" / "bench" / scene / "layout.json"
    glmap = GLMap(MapConfig(), embedder=embedder())
    seen = build_map_from_tour(
        bench_layout(layout), glmap, CameraSpec(320, 240), max_frames=max_frames
    )
    return {"tour": scene, "seen": sorted(seen), "map": map_fingerprint(glmap)}


def golden_record(max_steps: int = 40) -> list[dict[str, Any]]:
    """The test's record: actions and poses (6 decimals) of `GOLDEN_EPISODES`."""
    out = []
    for task, index, policy in GOLDEN_EPISODES:
        r = play(task, index, policy, max_steps)
        out.append(
            {
                "episode": r["episode"],
                "actions": "".join(ACTION_LETTERS[s["action"]] for s in r["steps"]),
                "poses": [[round(float(v), 6) for v in s["pose"]] for s in r["steps"]],
                "matched": [s["matched"] for s in r["steps"]],
                "instances": sorted((int(i), u[0], u[2]) for i, u in r["map"]["instances"].items()),
            }
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.regression.replay")
    parser.add_argument("--out", help="write the record here (JSON)")
    parser.add_argument("--compare", help="a record to compare with, field for field")
    parser.add_argument("--max-steps", type=int, default=120)
    parser.add_argument("--tour-frames", type=int, default=40)
    parser.add_argument("--golden", action="store_true", help=f"rewrite {GOLDEN.name}")
    parser.add_argument("--against", help="an older checkout: compare step by step in-process")
    parser.add_argument("--only", help="with --against: the runs whose name starts so")
    parser.add_argument(
        "--sqa", help="with --against: a `glmap eval sqa --out` folder to situate on"
    )
    args = parser.parse_args(argv)
    if args.golden:
        episodes = [json.dumps(e, separators=(",", ":")) for e in golden_record()]
        GOLDEN.write_text("[\n" + ",\n".join(episodes) + "\n]\n")
        print(f"wrote {GOLDEN}")
        return 0
    if args.against:
        tree, differing, total, ran = Path(args.against), 0, 0, 0
        report = Report(f"replay check against {tree}")
        runs = [
            (f"{t}/{i}/{p}", partial(play_against, tree, t, i, p, args.max_steps))
            for t, i, p in EPISODES
        ]
        runs += [(f"tour {s}", partial(tour_against, tree, s, args.tour_frames)) for s in TOURS]
        if args.sqa:
            runs = [("situate", partial(situate_against, tree, Path(args.sqa)))] + runs
        for name, run in runs:
            if args.only and not name.startswith(args.only):
                continue
            n, diff = run()
            total, ran, differing = total + n, ran + 1, differing + bool(diff)
            unit = "situations" if name == "situate" else "frames"
            verdict = "DIFFERENT:\n  " + "\n  ".join(diff) if diff else "identical"
            report.info(f"{name}: {n} {unit}, {verdict}")
        report.check(f"runs identical ({total} frames/situations)", ran - differing, ">=", ran)
        report.finish()
        return int(differing > 0)  # unlike a missed speed target, a difference is a failure
    record: dict[str, Any] = {"episodes": [], "tours": []}
    for task, index, policy in EPISODES:
        r = play(task, index, policy, args.max_steps)
        print(f"{r['episode']}: {len(r['steps'])} steps, success {r['success']}", flush=True)
        record["episodes"].append(r)
    for scene in TOURS:
        t = tour(scene, args.tour_frames)
        print(f"tour {scene}: {len(t['map']['instances'])} instances", flush=True)
        record["tours"].append(t)
    if args.out:
        Path(args.out).write_text(json.dumps(record, indent=0))
    if args.compare:
        before = json.loads(Path(args.compare).read_text())
        diff = differences(json.loads(json.dumps(record)), before)
        n = sum(len(e["steps"]) for e in record["episodes"])
        if diff:
            print("DIFFERENT from " + args.compare + ":\n  " + "\n  ".join(diff))
            return 1
        print(f"identical to {args.compare}: {n} steps, {len(record['tours'])} tours")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
