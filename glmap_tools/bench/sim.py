"""Simulator speed: env steps per second at 640x480 (target >= 5 on 2 CPU cores).

Measured by default on a large benchmark apartment (`--episode`, see worlds/splits.py), with
the reset time over that scene's benchmark episodes (goal field + first frame).

Usage: python -m glmap_tools.bench sim [--steps N] [--episode ID | --seed S] [--width W --height H]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402

from glmap_tools.bench._args import whole
from glmap_tools.bench.report import Report
from glmap_tools.sim.env import ObjectNavEnv
from glmap_tools.sim.render import CameraSpec
from glmap_tools.worlds.splits import bench_episode, load_split, make_env

TARGET_STEPS_PER_SECOND = 5.0
TARGET_RESET_MS = 100.0  # per reset on a benchmark scene: thousands of episodes are run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench sim")
    parser.add_argument("--steps", type=whole(1, 100_000), default=200)
    parser.add_argument(
        "--episode",
        default="bench/objectnav/s03-017",
        help="benchmark episode whose scene is measured ('' to use --seed)",
    )
    parser.add_argument("--seed", type=int, default=3, help="generated scene when --episode ''")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    args = parser.parse_args(argv)

    report = Report("bench sim")
    camera = CameraSpec(args.width, args.height)
    t0 = time.perf_counter()
    if args.episode:
        bench = bench_episode(args.episode)
        env = make_env(bench, camera)
        options = {"episode": bench.episode}
        scene = f"benchmark scene {bench.split}/{bench.scene} ({env.layout.name})"
    else:
        bench = None
        env = ObjectNavEnv(scene_seed=args.seed, camera=camera)
        options = {}
        scene = f"scene seed {args.seed}"
    t_make = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    env.reset(seed=0, options=options)
    env.step(1)  # warm up shaders
    t0 = time.perf_counter()
    steps = 0
    while steps < args.steps:
        action = int(rng.choice([1, 1, 2, 3]))  # never stop: measure steps, not resets
        _, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            env.reset(options=options)
    total = time.perf_counter() - t0
    t1 = time.perf_counter()
    for _ in range(20):
        env.renderer.render(env.state.pose(env.camera.camera_height))
    render_s = (time.perf_counter() - t1) / 20
    layout = env.layout
    lo, hi = layout.bounds()
    rate = steps / total
    report.info(
        f"{scene}: {len(layout.rooms)} rooms, {len(layout.objects)} objects, "
        f"{hi[0] - lo[0]:.1f} x {hi[1] - lo[1]:.1f} m; env made in {t_make:.2f} s"
    )
    report.info(
        f"resolution {args.width}x{args.height}: {1000 / rate:.1f} ms/step, "
        f"render {render_s * 1000:.1f} ms"
    )
    report.check(f"steps/s at {args.width}x{args.height}", rate, ">=", TARGET_STEPS_PER_SECOND)
    if bench is not None:
        same_scene = [
            b for b in load_split(bench.split, bench.task) if b.layout_path == bench.layout_path
        ]
        times = []
        for b in same_scene:
            env._fields.clear()  # measure each goal's field, not the cache
            t = time.perf_counter()
            env.reset(options={"episode": b.episode})
            times.append(time.perf_counter() - t)
        report.check(
            f"reset p50 over {len(times)} episodes of the scene (goal field + first frame)",
            1000 * float(np.median(times)),
            "<=",
            TARGET_RESET_MS,
            "ms",
        )
    env.close()
    return report.finish()
