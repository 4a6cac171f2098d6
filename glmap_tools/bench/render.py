"""Benchmark the splatting rasterizer: ms per frame, fast vs reference.

`python -m glmap_tools.bench render [--counts 10000 50000 ...] [--sizes 320x240 ...]`

The scene is N small Gaussians (std 1-3 cm per axis, random orientation, opacity 0.5-1)
spread uniformly over the image at 1-5 m in front of the camera. The fast path is timed as
the median (and min) of `--repeats` frames after a warm-up call; the process's first call,
which compiles the numba kernels or loads them from the on-disk cache, is reported apart
(set NUMBA_CACHE_DIR to an empty folder to see a cold compile). The reference renders one
frame of the same view at `--reference-size` (its per-pixel cost does not depend on the
image size: every pixel visits every Gaussian) and is scaled by the pixel ratio; it is
skipped past `--reference-max` Gaussians. Sample images go to `--out` (PNG).

Where the fast path's time goes is printed per stage (projection, depth sort, binning into
tile lists, rasterization with compositing), median wall and process CPU time over the
same number of frames; CPU above wall means the stage ran on several threads.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import cv2
import numba
import numpy as np

from glmap_tools.bench._args import image_size, whole
from glmap_tools.bench.report import Report
from glmap_tools.cli_format import HelpWithDefaults
from glmap_tools.gaussians._render_numba import render_fast
from glmap_tools.gaussians.render import render, warm_up
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.geometry.rotations import rotations_from_quaternions

HFOV_DEG = 79.0


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """[n, 3, 3] uniformly random rotation matrices (from unit quaternions)."""
    return rotations_from_quaternions(rng.normal(size=(n, 4)))


def bench_scene(n: int, pose: Pose, intrinsics: Intrinsics, seed: int = 0) -> GaussianSet:
    """N small random Gaussians covering the view of `intrinsics` at `pose`, 1-5 m away."""
    rng = np.random.default_rng(seed)
    k = intrinsics
    z = rng.uniform(1.0, 5.0, n)
    u = rng.uniform(-0.5, k.width - 0.5, n)
    v = rng.uniform(-0.5, k.height - 0.5, n)
    points_cam = np.stack([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z], axis=1)
    rot = random_rotations(rng, n)
    sigma = rng.uniform(0.01, 0.03, (n, 3))
    covs = np.einsum("nij,nj,nkj->nik", rot, sigma**2, rot) + 1e-6 * np.eye(3)
    colors = rng.uniform(0.0, 1.0, (n, 3))
    return GaussianSet(
        pose.transform_points(points_cam),
        covs,
        colors,
        rng.uniform(0.5, 1.0, n),
        np.ones(n),
    )


def _time_ms(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """(median, min) wall time of `repeats` calls, in ms."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1000.0 * float(np.median(times)), 1000.0 * float(np.min(times))


def _parse_size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(w), int(h)


TARGETS_MS = {(50_000, 320, 240): 15.0, (1_000_000, 640, 480): 200.0}  # issue 31
STAGES = ("project", "sort", "bin", "rasterize")


def stage_times(
    scene: GaussianSet, pose: Pose, intrinsics: Intrinsics, repeats: int
) -> dict[str, tuple[float, float]]:
    """Median (wall ms, CPU ms) of each fast-path stage over `repeats` frames."""
    laps: dict[str, list[tuple[float, float]]] = {}
    for _ in range(repeats):
        render_fast(scene, pose, intrinsics, (1.0, 1.0, 1.0), 0.05, 50.0, stages=laps)
    return {
        name: (1000.0 * float(np.median([w for w, _ in laps[name]])),
               1000.0 * float(np.median([c for _, c in laps[name]])))
        for name in STAGES
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.bench render",
        description=__doc__,
        formatter_class=HelpWithDefaults,
    )
    parser.add_argument(
        "--counts",
        type=whole(1, 10_000_000),
        nargs="+",
        default=[10_000, 50_000, 100_000, 1_000_000],
    )
    parser.add_argument("--sizes", type=image_size, nargs="+", default=["320x240", "640x480"])
    parser.add_argument("--repeats", type=whole(1, 10_000), default=10)
    parser.add_argument("--reference-size", type=image_size, default="32x24")
    parser.add_argument("--reference-max", type=whole(1, 10_000_000), default=1_000_000)
    parser.add_argument("--out", type=Path, default=Path("out/bench_render"))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    args.out.mkdir(parents=True, exist_ok=True)
    report = Report("bench render")
    pose = Pose.from_position_heading(0.0, 0.0, 1.5, heading=0.3)
    load_before = os.getloadavg()[0]
    first = warm_up()
    print(
        f"first call {first:.2f} s (numba compile, or loading it from the on-disk cache), "
        f"then {1000 * warm_up():.1f} ms; numba threads "
        f"{numba.get_num_threads()}, layer {numba.threading_layer()}"
    )
    ref_w, ref_h = _parse_size(args.reference_size)
    cases = [(n, *_parse_size(size)) for size in args.sizes for n in args.counts]
    fast: dict[tuple[int, int, int], tuple[float, float]] = {}
    stages: dict[tuple[int, int, int], dict[str, tuple[float, float]]] = {}
    for n, w, h in cases:  # all fast timings first, close together in time
        intrinsics = Intrinsics.from_fov(w, h, HFOV_DEG)
        scene = bench_scene(n, pose, intrinsics, args.seed)
        result = render(scene, pose, intrinsics)  # warm-up
        fast[n, w, h] = _time_ms(partial(render, scene, pose, intrinsics), args.repeats)
        stages[n, w, h] = stage_times(scene, pose, intrinsics, args.repeats)
        path = args.out / f"render_{n}_{w}x{h}.png"
        cv2.imwrite(str(path), cv2.cvtColor(result.to_uint8(), cv2.COLOR_RGB2BGR))
    load_after_fast = os.getloadavg()[0]
    print("fast path by stage, median wall / CPU ms: " + ", ".join(STAGES))
    for (n, w, h), by_stage in stages.items():
        cells = "  ".join(f"{wall:6.2f} / {cpu:6.2f}" for wall, cpu in by_stage.values())
        print(f"{n:>9} {f'{w}x{h}':>9}  {cells}")
    print(f"{'N':>9} {'size':>9} {'fast ms':>8} {'(min)':>7} {'ref ms est.':>12} {'ref/fast':>9}")
    for n, w, h in cases:
        fast_ms, fast_min = fast[n, w, h]
        ref_text, ratio_text = "skipped", "-"
        if n <= args.reference_max:
            intrinsics = Intrinsics.from_fov(w, h, HFOV_DEG)
            small = intrinsics.scaled(min(ref_w, w), min(ref_h, h))
            scene = bench_scene(n, pose, intrinsics, args.seed)
            ref_small, _ = _time_ms(partial(render, scene, pose, small, backend="reference"), 1)
            ref_ms = ref_small * (w * h) / (small.width * small.height)
            ref_text = f"{ref_ms:,.0f}"
            ratio_text = f"{ref_ms / fast_ms:,.0f}x"
        print(
            f"{n:>9} {f'{w}x{h}':>9} {fast_ms:>8.1f} {fast_min:>7.1f} {ref_text:>12} "
            f"{ratio_text:>9}",
            flush=True,
        )
    for (n, w, h), target in TARGETS_MS.items():
        if (n, w, h) in fast:
            name = f"render of {n} Gaussians at {w}x{h}, median"
            report.check(name, fast[n, w, h][0], "<=", target, "ms")
    print(
        f"load average {load_before:.2f} before, {load_after_fast:.2f} after the fast timings; "
        "other processes on the 2 cores slow the parallel kernels, compare low-load figures"
    )
    print(
        f"fast: median (and min) of {args.repeats} frames after a warm-up; reference: one "
        f"frame of the same view at {args.reference_size}, scaled by the pixel ratio; "
        f"images in {args.out}/"
    )
    return report.finish()
