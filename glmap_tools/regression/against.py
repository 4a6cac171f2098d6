"""`replay --against DIR`: this tree and an older checkout fed the same frames in one process.

The older tree's `OLD_MODULES` (the frame's path into the map, the policy's decision, the
situation reader) are loaded beside this tree's modules; every episode and tour frame goes
to both, and the maps, reports, decisions and navigation states are compared after every
step. No quiet machine needed: both sides see the same rendered frames.
"""

from __future__ import annotations

import importlib.util
import inspect
import json
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

import glmap_tools.data
from glmap_tools.language.minilm import default_embedder as embedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState, decide
from glmap_tools.nav.config import ACTIONS
from glmap_tools.nav.episode import agent_of, observation_frame, remember
from glmap_tools.nav.perceive import frame_score
from glmap_tools.regression.fingerprint import differences, digest, map_fingerprint, report_fields
from glmap_tools.sim.render import CameraSpec
from glmap_tools.sqa.situate import situate
from glmap_tools.worlds.map_eval import tour_frames
from glmap_tools.worlds.splits import bench_layout, load_split, make_env


def _module_from(path: Path, name: str) -> Any:
    """Load the module at `path` under `name` (beside this tree's modules)."""

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
            digest(d.plan.path),
        ],
        "value": None if d.value is None else digest(d.value.values),
        "frontiers": [repr((f.centroid, f.size, f.distance, f.target)) for f in d.frontiers],
        "matched": d.matched_unit,
        "occupancy": [d.occupancy.origin, digest(d.occupancy.state)],
        "scores": digest(np.array(sorted(d.scores.items()), dtype=float)),
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
    "glmap_tools.nav.footprint",
    "glmap_tools.nav.waypoint",
    "glmap_tools.nav.policy",
    "glmap_tools.sqa.situate",
)


def _old_modules(tree: Path) -> dict[str, Any]:
    """OLD_MODULES as in `tree` (those it has), each calling the others' old versions."""

    paths = {name: tree / (name.replace(".", "/") + ".py") for name in OLD_MODULES}
    old = {
        name: _module_from(path, "_old_" + name.replace(".", "_"))
        for name, path in paths.items()
        if path.exists()
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

        old = _old_modules(tree)
        self.fusion, self.policy = old["glmap_tools.map.fusion"], old["glmap_tools.nav.policy"]
        self.new, self.old = (GLMap(MapConfig(), embedder=embedder()) for _ in range(2))

    def integrate(self, frame: Any, sem: Any, where: str) -> list[str]:
        new = self.new.integrate(frame, sem)
        old = self.old.integrate(frame, sem, planner=self.fusion.plan_frame)
        a = [report_fields(new), new.model_dump(), map_fingerprint(self.new)]
        b = [report_fields(old), old.model_dump(), map_fingerprint(self.old)]
        return differences(json.loads(json.dumps(a)), json.loads(json.dumps(b)), where)


def play_against(
    tree: Path, task: str, index: int, policy: str, max_steps: int
) -> tuple[int, list[str]]:
    """Play one tune episode with this tree; (steps, differences from `tree` at any step).

    Each frame goes into both maps and both policies' memories, then to both `decide`s (an
    older `decide` that takes the frame remembers it itself)."""

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
        "h_r": digest(s.h_r.values),
        "h_o": None if s.h_o is None else digest(s.h_o.values),
        "scores": [repr(u.score) for u in s.anchors + s.facing],
    }
