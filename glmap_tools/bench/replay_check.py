"""`python -m glmap_tools.bench replay-check`: seeded episodes and tours, recorded field for field.

A refactor that claims "behaviour unchanged" records a run before and after and compares:

    python -m glmap_tools.bench replay-check --out before.json          # on the old tree
    python -m glmap_tools.bench replay-check --out after.json --compare before.json

Each episode (tune split, simulator seed 0) records every step's action, pose, waypoint,
plan length, matched unit and the frame's update report, and at its end a fingerprint of
the map: every unit's fields with SHA-256 digests of its arrays (embedding, Gaussians),
the index grid, occupancy and structure layer. Each tour (bench scene, `sim.tour` frames)
records the same fingerprint. Floats are kept as `repr`, so equality means bit-identical.

The simulator's frames can differ in a last bit from run to run on a loaded machine (a few
Gaussians of one instance then differ between two runs of the same code), so a record
compares commits only on a quiet machine. `--against DIR` needs no quiet machine: one
process plays every episode and tour once and feeds each frame to both `plan_frame` and
`decide` of this tree and of the tree at DIR (its `map/fusion.py` and `nav/policy.py`,
loaded beside this tree's modules), comparing the maps, reports, decisions and navigation
states after every step:

    python -m glmap_tools.bench replay-check --against /path/to/old/checkout

`--golden` writes the short record the test `tests/test_replay_golden.py` holds the code
to (`tests/data/replay_golden.json`: three episodes' actions and poses, rounded).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools.bench.report import Report

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


def _digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def map_fingerprint(glmap: Any) -> dict[str, Any]:
    """Every unit's fields (arrays as digests), the grid, occupancy and structure digests."""
    inst = {
        str(i): [
            u.label,
            u.text,
            u.observations,
            u.first_frame,
            u.last_frame,
            _digest(u.embedding),
            len(u.gaussians),
            _digest(
                u.gaussians.means,
                u.gaussians.covs,
                u.gaussians.colors,
                u.gaussians.opacities,
                u.gaussians.counts,
            ),
        ]
        for i, u in sorted(glmap.instances.items())
    }
    regions = {
        str(i): [
            r.text,
            list(r.instance_ids),
            r.observations,
            r.first_frame,
            r.last_frame,
            _digest(r.embedding),
        ]
        for i, r in sorted(glmap.regions.items())
    }
    cells = [
        (uid, sorted(glmap.grid.cells_of_unit(uid)))
        for uid in sorted(set(glmap.instances) | set(glmap.regions))
    ]
    occ = sorted(glmap.occupancy.chunks.items())
    structure = glmap.structure.gaussians()
    return {
        "instances": inst,
        "regions": regions,
        "grid": hashlib.sha256(repr(cells).encode()).hexdigest()[:16],
        "occupancy": _digest(np.array([k for k, _ in occ]), *(v for _, v in occ)),
        "structure": [len(structure), _digest(structure.means, structure.covs, structure.colors)],
        "next_id": glmap.next_id,
        "floor_z": repr(glmap.floor_z),
        "fused_into": sorted(glmap.fused_into.items()),
    }


def _report(report: Any) -> list[Any]:
    return [
        [(c.local_id, c.global_id) for c in report.instances_added],
        [(c.local_id, c.global_id, repr(c.similarity)) for c in report.instances_merged],
        [(c.local_id, c.global_id) for c in report.regions_added],
        [(c.local_id, c.global_id, repr(c.similarity)) for c in report.regions_merged],
        sorted(report.fused.items()),
        [(s.local_id, s.kind) for s in report.skipped],
        report.gaussians_added,
        report.structure_gaussians,
    ]


def play(task: str, index: int, policy: str, max_steps: int) -> dict[str, Any]:
    """Play one tune episode (`nav.episode.play`); every step's decision and the final
    map's fingerprint."""
    from glmap_tools.bench._nav_loop import embedder
    from glmap_tools.map import GLMap, MapConfig
    from glmap_tools.nav import NavConfig
    from glmap_tools.nav.episode import play as play_steps
    from glmap_tools.sim.benchmark import load_split, make_env
    from glmap_tools.sim.render import CameraSpec

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
                    "scores": _digest(np.array(sorted(d.scores.items()), dtype=float)),
                    "report": _report(step.report),
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
    import glmap_tools.data
    from glmap_tools.bench._nav_loop import embedder
    from glmap_tools.map import GLMap, MapConfig
    from glmap_tools.sim.benchmark import bench_layout
    from glmap_tools.sim.map_eval import build_map_from_tour
    from glmap_tools.sim.render import CameraSpec

    layout = Path(glmap_tools.data.__path__[0]) / "benchmark" / "bench" / scene / "layout.json"
    glmap = GLMap(MapConfig(), embedder=embedder())
    seen = build_map_from_tour(
        bench_layout(layout), glmap, CameraSpec(320, 240), max_frames=max_frames
    )
    return {"tour": scene, "seen": sorted(seen), "map": map_fingerprint(glmap)}


def _module_from(path: Path, name: str) -> Any:
    """Load the module at `path` under `name` (beside this tree's modules)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None, path
    if name not in sys.modules:
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up there
        spec.loader.exec_module(module)
    return sys.modules[name]


def _decision(d: Any, state: Any) -> dict[str, Any]:
    """A decision and the navigation state after it, floats and arrays exact."""
    wp = d.waypoint
    return {
        "action": d.action,
        "waypoint": [wp.kind, repr(wp.xy), wp.unit_id, repr(wp.score), wp.reason],
        "plan": [
            repr(d.plan.length),
            d.plan.reachable,
            repr(d.plan.goal_xy),
            d.plan.boxed,
            _digest(d.plan.path),
        ],
        "value": None if d.value is None else _digest(d.value.values),
        "frontiers": [repr((f.centroid, f.size, f.distance, f.target)) for f in d.frontiers],
        "matched": d.matched_unit,
        "occupancy": [d.occupancy.origin, _digest(d.occupancy.state)],
        "scores": _digest(np.array(sorted(d.scores.items()), dtype=float)),
        "state": [
            repr(state.avoid),
            sorted(state.rejected_units),
            sorted(state.blocked),
            repr(state.last_xy),
            repr(state.best_distance),
            state.since_progress,
            state.turns_in_place,
            state.steps,
            state.last_action,
        ],
    }


# The modules whose old versions a comparison loads (what a refactor of the frame's path
# and the policy's decision touches); everything else is shared with this tree.
OLD_MODULES = (
    "glmap_tools.map.fusion",
    "glmap_tools.nav.waypoint",
    "glmap_tools.nav.policy",
    "glmap_tools.sqa.situate",
)


def _old_modules(tree: Path) -> dict[str, Any]:
    """OLD_MODULES as in `tree`, each calling the others' old versions."""
    import importlib

    old = {
        name: _module_from(
            tree / (name.replace(".", "/") + ".py"), "_old_" + name.replace(".", "_")
        )
        for name in OLD_MODULES
    }
    for name, module in old.items():  # point names imported from a live module at the old one
        live = importlib.import_module(name)
        for other in old.values():
            for attr, obj in list(vars(other).items()):
                if obj is not None and obj is getattr(live, attr, None) and hasattr(module, attr):
                    setattr(other, attr, getattr(module, attr))
    return old


class _TwoTrees:
    """This tree's and an older tree's `plan_frame` and `decide`, fed the same frames."""

    def __init__(self, tree: Path) -> None:
        from glmap_tools.bench._nav_loop import embedder
        from glmap_tools.map import GLMap, MapConfig

        old = _old_modules(tree)
        self.fusion, self.policy = old["glmap_tools.map.fusion"], old["glmap_tools.nav.policy"]
        self.new, self.old = (GLMap(MapConfig(), embedder=embedder()) for _ in range(2))

    def integrate(self, frame: Any, sem: Any, where: str) -> list[str]:
        new = self.new.integrate(frame, sem)
        old = self.old.integrate(frame, sem, planner=self.fusion.plan_frame)
        a = [_report(new), new.model_dump(), map_fingerprint(self.new)]
        b = [_report(old), old.model_dump(), map_fingerprint(self.old)]
        return differences(json.loads(json.dumps(a)), json.loads(json.dumps(b)), where)


def play_against(
    tree: Path, task: str, index: int, policy: str, max_steps: int
) -> tuple[int, list[str]]:
    """Play one tune episode with this tree; (steps, differences from `tree` at any step).

    Each frame goes into both maps and both policies' memories, then to both `decide`s (an
    older `decide` that takes the frame remembers it itself)."""
    import inspect

    from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState, decide
    from glmap_tools.nav.config import ACTIONS
    from glmap_tools.nav.episode import agent_of, observation_frame, remember
    from glmap_tools.nav.perceive import frame_score
    from glmap_tools.sim.benchmark import load_split, make_env
    from glmap_tools.sim.render import CameraSpec

    two = _TwoTrees(tree)
    be = load_split("tune", task)[index]
    env = make_env(be, camera=CameraSpec(320, 240), max_steps=max_steps)
    config = NavConfig.for_task(be.task)
    state, old_state = NavState(), two.policy.NavState()
    old_takes_frame = "frame" in inspect.signature(two.policy.decide).parameters
    steps = 0
    try:
        obs, info = env.reset(seed=0, options={"episode": be.episode})
        goal = obs["goal"]
        for st, glmap in ((state, two.new), (old_state, two.old)):
            st.scorer = EmbeddingScorer(glmap.embedder)
        while True:
            where = f"{task}/{index}/{policy} step {steps}"
            frame, sem = observation_frame(obs, info, env.camera.intrinsics)
            diff = two.integrate(frame, sem, where)
            memories = [(state, two.new)] + ([] if old_takes_frame else [(old_state, two.old)])
            for st, glmap in memories:
                remember(st, glmap, frame, frame_score(glmap, goal, st.scorer, sem))
            x, y, heading = agent_of(info)
            seen = {"frame": frame, "semantics": sem} if old_takes_frame else {}
            d = decide(two.new, (x, y), heading, goal, policy=policy, state=state, config=config)
            old = two.policy.decide(
                two.old,
                (x, y),
                heading,
                goal,
                policy=policy,
                state=old_state,
                config=config,
                **seen,
            )
            diff += differences(
                json.loads(json.dumps(_decision(d, state))),
                json.loads(json.dumps(_decision(old, old_state))),
                where,
            )
            steps += 1
            if diff:
                return steps, diff
            obs, _, term, trunc, info = env.step(ACTIONS.index(d.action))
            if term or trunc:
                return steps, []
    finally:
        env.close()


def tour_against(tree: Path, scene: str, max_frames: int) -> tuple[int, list[str]]:
    """Integrate a bench scene's tour into both trees' maps; (frames, differences)."""
    import glmap_tools.data
    from glmap_tools.sim.benchmark import bench_layout
    from glmap_tools.sim.map_eval import tour_frames
    from glmap_tools.sim.render import CameraSpec

    two = _TwoTrees(tree)
    layout = Path(glmap_tools.data.__path__[0]) / "benchmark" / "bench" / scene / "layout.json"
    n = 0
    for frame, sem, _ in tour_frames(
        bench_layout(layout), CameraSpec(320, 240), max_frames=max_frames
    ):
        diff = two.integrate(frame, sem, f"tour {scene} frame {n}")
        n += 1
        if diff:
            return n, diff
    return n, []


def situate_against(tree: Path, results: Path) -> tuple[int, list[str]]:
    """`situate` of both trees on the maps and situations of a `glmap eval sqa --out`
    folder; (situations, differences)."""
    import shutil
    import tempfile

    from glmap_tools.bench._nav_loop import embedder
    from glmap_tools.map import GLMap
    from glmap_tools.sqa.situate import situate

    old = _old_modules(tree)["glmap_tools.sqa.situate"]
    n, diff = 0, []
    for scene in sorted((results / "scenes").glob("*.json")):
        texts = sorted({r["situation"] for r in json.loads(scene.read_text())["records"]})
        with tempfile.TemporaryDirectory() as tmp:  # opening a store may write to it
            path = Path(tmp) / "map.glmap"
            shutil.copy(results / "maps" / f"{scene.stem}.glmap", path)
            glmap = GLMap.open(path, embedder=embedder())
            labels = sorted({u.label for u in glmap.instances.values()})[:8]
            texts += [f"I am next to the {a}, facing the {b}." for a in labels for b in labels]
            texts += [f"I am at the {a}, the {b} is on my left." for a in labels for b in labels]
            texts += [f"The {b} is behind me." for b in labels]
            texts += [f"sitting in the {r.text.split('|')[0][:40]}" for r in glmap.regions.values()]
            try:
                for text in texts:
                    a, b = (
                        json.loads(json.dumps(_situation(f(glmap, text)), default=repr))
                        for f in (situate, old.situate)
                    )
                    diff += differences(a, b, f"{scene.stem} {text[:50]!r}")
                    n += 1
            finally:
                glmap.close()
    return n, diff


def _situation(s: Any) -> dict[str, Any]:
    return {
        **s.as_dict(),
        "pose": [repr(s.x), repr(s.y), repr(s.heading)],
        "peaks": [repr(s.peak_r), repr(s.peak_o)],
        "ids": [s.anchor_id, s.facing_id],
        "h_r": _digest(s.h_r.values),
        "h_o": None if s.h_o is None else _digest(s.h_o.values),
        "scores": [repr(u.score) for u in s.anchors + s.facing],
    }


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


def differences(a: Any, b: Any, where: str = "", limit: int = 20) -> list[str]:
    """Paths where two JSON values differ (at most `limit`)."""
    out: list[str] = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}/{k}: only in {'after' if k in a else 'before'}")
            else:
                out += differences(a[k], b[k], f"{where}/{k}", limit - len(out))
            if len(out) >= limit:
                break
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{where}: length {len(a)} != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            out += differences(x, y, f"{where}[{i}]", limit - len(out))
            if len(out) >= limit:
                break
    elif a != b:
        out.append(f"{where}: {a!r} != {b!r}")
    return out[:limit]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench replay-check")
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
        report = Report(f"bench replay-check against {tree}")
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
