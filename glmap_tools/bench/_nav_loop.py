"""Closed-loop helpers of `bench nav-core`: run a policy in the simulator, calibrate f_S.

Only the tune split (scene seeds 1000+) is used here; the bench split is for reported
figures and is never tuned on.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from glmap_tools.geometry import Pose  # noqa: E402
from glmap_tools.geometry.frame import RGBDFrame  # noqa: E402
from glmap_tools.map import GLMap, MapConfig  # noqa: E402
from glmap_tools.nav import EmbeddingScorer, NavConfig, NavState, decide, map_units  # noqa: E402
from glmap_tools.perception.annotated import semantics_from_annotation  # noqa: E402
from glmap_tools.sim.benchmark import BenchEpisode, bench_layout, load_split, make_env  # noqa: E402
from glmap_tools.sim.render import CameraSpec  # noqa: E402

ACTION_IDS = {"stop": 0, "move_forward": 1, "turn_left": 2, "turn_right": 3}
_EMBEDDER: Any = None


def embedder() -> Any:
    """The bundled MiniLM embedder, loaded once."""
    global _EMBEDDER
    if _EMBEDDER is None:
        from glmap_tools.language.embed import default_embedder

        _EMBEDDER = default_embedder()
    return _EMBEDDER


def run_episode(
    be: BenchEpisode,
    policy: str,
    max_steps: int = 500,
    timings: bool = False,
    camera: CameraSpec | None = None,
) -> dict[str, Any]:
    """Run `policy` on one episode; returns success, spl, steps, distance and timings.

    Timings (ms per step): process CPU time of render (env.step: move, render, annotate),
    integrate and decide, and the wall time of the whole step.
    """
    env = make_env(be, camera=camera or CameraSpec(320, 240), max_steps=max_steps)
    t_render: list[float] = []
    t_integrate: list[float] = []
    t_decide: list[float] = []
    t_wall: list[float] = []
    try:
        obs, info = env.reset(seed=0, options={"episode": be.episode})
        glmap = GLMap(MapConfig(), embedder=embedder())
        state, config = NavState(), NavConfig.for_task(be.task)
        intr = env.camera.intrinsics
        while True:
            frame = RGBDFrame(obs["rgb"], obs["depth"], intr, Pose(obs["pose"].astype(np.float64)))
            sem = semantics_from_annotation(info["instance_mask"], info["annotation"])
            w0 = time.perf_counter()
            t0 = time.process_time()
            glmap.integrate(frame, sem)
            t1 = time.process_time()
            d = decide(
                glmap,
                (float(info["position"][0]), float(info["position"][1])),
                float(info["heading"]),
                obs["goal"],
                policy=policy,
                state=state,
                config=config,
                frame=frame,
                semantics=sem,
            )
            t2 = time.process_time()
            obs, _, term, trunc, info = env.step(ACTION_IDS[d.action])
            t3 = time.process_time()
            t_wall.append((time.perf_counter() - w0) * 1000)
            t_integrate.append((t1 - t0) * 1000)
            t_decide.append((t2 - t1) * 1000)
            t_render.append((t3 - t2) * 1000)
            if term or trunc:
                break
    finally:
        env.close()
    out: dict[str, Any] = {
        "episode": be.episode_id,
        "goal": be.episode.goal_text,
        "success": bool(info["success"]),
        "spl": float(info["spl"]),
        "steps": int(info["steps"]),
        "distance_to_goal": float(info["distance_to_goal"]),
        "matched": d.matched_unit,
        "last": d.waypoint.reason,
    }
    if timings:
        out["timings"] = {
            "render": t_render,
            "integrate": t_integrate,
            "decide": t_decide,
            "wall": t_wall,
        }
    return out


def closed_loop(task: str, indices: Sequence[int], policies: Sequence[str]) -> int:
    """Print each episode's outcome and the success rate per policy (tune split only)."""
    episodes = load_split("tune", task)
    for policy in policies:
        results = [run_episode(episodes[k], policy) for k in indices]
        for r in results:
            print(
                f"{policy:15s} {r['episode']} {r['goal'][:40]!r}: success {r['success']} spl "
                f"{r['spl']:.2f} steps {r['steps']} left {r['distance_to_goal']:.2f} m; "
                f"{r['last']}",
                flush=True,
            )
        sr = np.mean([r["success"] for r in results])
        spl = np.mean([r["spl"] for r in results])
        print(f"{policy}: SR {sr:.2f}, SPL {spl:.2f} over {len(results)} tune episodes", flush=True)
    return 0


def calibration_pairs() -> list[tuple[str, float, bool, int]]:
    """(task, cosine, is a goal object, observations) for every tune goal x mapped instance.

    One map per tune scene from `sim.tour` at 320x240; map instances are matched to layout
    objects by `sim.map_eval.evaluate_instances`; instances matched to no object are left
    out (they are duplicates or fragments, neither clearly right nor wrong).
    """
    from glmap_tools.sim.map_eval import build_map_from_tour, evaluate_instances

    scorer = EmbeddingScorer(embedder(), floor=0.0)
    pairs: list[tuple[str, float, bool, int]] = []
    maps: dict[str, Any] = {}
    for task in ("objectnav", "instnav"):
        goals: dict[str, dict[str, set[int]]] = {}
        for be in load_split("tune", task):
            goals.setdefault(str(be.layout_path), {})[be.episode.goal_text] = set(
                be.episode.goal_object_ids
            )
        for path, by_goal in goals.items():
            if path not in maps:
                layout = bench_layout(path)
                glmap = GLMap(MapConfig(), embedder=embedder())
                seen = build_map_from_tour(layout, glmap, CameraSpec(320, 240))
                maps[path] = (glmap, evaluate_instances(glmap, layout, seen))
            glmap, ev = maps[path]
            units = map_units(glmap, "instances")
            for goal, ids in by_goal.items():
                for u, c in zip(units, scorer.cosines(goal, units), strict=True):
                    obj = ev.matched.get(u.unit_id)
                    if obj is not None:
                        pairs.append((task, float(c), obj in ids, u.observations))
    return pairs


def calibrate() -> int:
    """Print precision/recall of the stop rule per task, threshold and min observations."""
    pairs = calibration_pairs()
    floor = EmbeddingScorer.DEFAULT_FLOOR
    for task in ("objectnav", "instnav"):
        rows = [p for p in pairs if p[0] == task]
        cos = np.array([p[1] for p in rows])
        pos = np.array([p[2] for p in rows])
        obs = np.array([p[3] for p in rows])
        neg = cos[~pos]
        print(
            f"{task}: {int(pos.sum())} goal-instance pairs, {int((~pos).sum())} others; "
            f"cosine of others: median {np.median(neg):.3f}, 90th pct {np.percentile(neg, 90):.3f}"
        )
        for min_obs in (1, 2, 3):
            cells = []
            for t_cos in np.arange(0.45, 0.90, 0.05):
                sel = (cos >= t_cos) & (obs >= min_obs)
                tp, fp = int((sel & pos).sum()), int((sel & ~pos).sum())
                s = (t_cos - floor) / (1 - floor)
                cells.append(
                    f"s>={s:.2f}: P {tp / max(tp + fp, 1):.2f} R {tp / max(pos.sum(), 1):.2f}"
                )
            print(f"  min_observations {min_obs}: " + " | ".join(cells))
    return 0
