"""Simulator speed: env steps per second at 640x480 (target >= 5 on 2 CPU cores).

Usage: python -m glmap_tools.bench sim [--steps N] [--seed S] [--width W --height H]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np  # noqa: E402

TARGET_STEPS_PER_SECOND = 5.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench sim")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    args = parser.parse_args(argv)

    from glmap_tools.sim.env import ObjectNavEnv
    from glmap_tools.sim.render import CameraSpec

    t0 = time.perf_counter()
    env = ObjectNavEnv(scene_seed=args.seed, camera=CameraSpec(args.width, args.height))
    t_make = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    env.step(1)  # warm up shaders
    render_s = 0.0
    t0 = time.perf_counter()
    steps = 0
    while steps < args.steps:
        action = int(rng.choice([1, 1, 2, 3]))  # never stop: measure steps, not resets
        _, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            env.reset()
    total = time.perf_counter() - t0
    t1 = time.perf_counter()
    for _ in range(20):
        env.renderer.render(env.state.pose(env.camera.camera_height))
    render_s = (time.perf_counter() - t1) / 20
    layout = env.layout
    rate = steps / total
    print(
        f"scene seed {args.seed}: {len(layout.rooms)} rooms, {len(layout.objects)} objects; "
        f"env made in {t_make:.2f} s"
    )
    print(f"resolution {args.width}x{args.height}, {os.cpu_count()} CPUs")
    print(f"steps/s: {rate:.1f}  ({1000 / rate:.1f} ms/step, render {render_s * 1000:.1f} ms)")
    print(
        f"target {TARGET_STEPS_PER_SECOND:.0f} steps/s: ratio {rate / TARGET_STEPS_PER_SECOND:.2f}"
    )
    env.close()
    return 0
