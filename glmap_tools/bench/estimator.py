"""Benchmark of the Gaussian Estimator: `python -m glmap_tools.bench estimator`.

A synthetic 640x480 RGB-D frame (room corner with floor, walls, ceiling, boxes and spheres,
ray-cast exactly, colour noise 0.02) is back-projected to ~300k points and fitted at 1.5 cm
and 2 cm voxels. Prints ms per frame for the fast path and the reference (the reference
runs on a subsample and is extrapolated by point count), Gaussians before/after merge,
bytes per Gaussian, the speed ratio, ms per 50k-point instance and the first-call time.

Then the bundled Redwood frame 0: the fast fit with and without the merge against the
reference estimator (`backend="reference"`) on the same cloud in the same run, as process
CPU ms and the ratio (the reference once per case, the fast path the median of
`--repeats`), what the merge adds to the fit, and where the time goes: each stage's process
CPU ms, and the fit with the merge's decisions (its pairs and their union) taken as given.
With `--official PATH` (a clone of the paper's code), the official estimator on that frame
too, in the same run (`_official.py`).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numba
import numpy as np

from glmap_tools.bench._args import whole
from glmap_tools.bench._official import OFFICIAL_URL, load_official_estimator, official_times
from glmap_tools.bench.report import Report
from glmap_tools.cli_format import HelpWithDefaults
from glmap_tools.gaussians import _estimator_fast
from glmap_tools.gaussians._estimator_fast import StageTimes, fit_fast
from glmap_tools.gaussians.estimator import EstimatorConfig, GaussianEstimator, validate_cloud
from glmap_tools.gaussians.merge import remerge
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose, backproject, depth_from_uint16

# Imports inside functions stay there: gaussians load on first use; an import that may fail is
# caught where it is used.

REDWOOD_TARGET_MS = 13.0  # fit and merge of the bundled Redwood frame 0 at 1.5 cm
OFFICIAL_TARGET_RATIO = 60.0  # fit and merge of that frame against the official estimator
OFFICIAL_ROUNDS = 7  # alternating rounds of the official estimator and ours
FIT_STAGES = ("input checks", "voxelise", "block neighbours", "voxel moments", "neighbourhood sums")
MERGE_DECISIONS = ("mergeable pairs", "capped union")
ROOM = (2.8, 2.5, 2.5)  # corner walls at x = 2.8 and y = 2.5, ceiling at z = 2.5
EYE, TARGET = (0.4, 0.3, 1.3), (2.4, 2.0, 0.5)  # camera position and look-at point, metres
BOXES = [  # (lo, hi, rgb)
    ((1.6, 1.3, 0.0), (2.3, 2.0, 0.75), (0.55, 0.35, 0.2)),
    ((1.0, 1.9, 0.0), (1.5, 2.4, 0.45), (0.2, 0.4, 0.7)),
    ((2.1, 0.3, 0.0), (2.7, 0.8, 1.1), (0.85, 0.85, 0.8)),
]
SPHERES = [  # (centre, radius, rgb)
    ((1.9, 1.65, 0.9), 0.15, (0.9, 0.2, 0.2)),
    ((1.3, 1.0, 0.25), 0.25, (0.2, 0.7, 0.3)),
    ((1.2, 2.2, 0.6), 0.1, (0.95, 0.8, 0.1)),
]


def synthetic_frame(
    width: int = 640,
    height: int = 480,
    noise: float = 0.02,
    seed: int = 0,
    pose: Pose | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World points [N, 3] and colours [N, 3] of the ray-cast room-corner frame.

    Args:
        width, height: image size in pixels (79 degree horizontal field of view).
        noise: standard deviation of the colour noise (RGB in [0, 1]).
        seed: seed of the colour noise.
        pose: the camera; by default at EYE looking at TARGET.
    """
    intrinsics = Intrinsics.from_fov(width, height, 79.0)
    if pose is None:
        pose = Pose.looking_at(np.array(EYE), np.array(TARGET))
    v, u = np.mgrid[0:height, 0:width]
    cam = np.stack(
        [
            (u - intrinsics.cx) / intrinsics.fx,
            (v - intrinsics.cy) / intrinsics.fy,
            np.ones(u.shape),
        ],
        axis=-1,
    ).reshape(-1, 3)
    dirs = cam @ pose.rotation.T  # world ray per pixel, camera-z component 1
    eye = pose.translation
    t = np.full(len(dirs), np.inf)
    rgb = np.zeros((len(dirs), 3))

    def hit(t_new: np.ndarray, color: np.ndarray) -> None:
        closer = (t_new > 1e-6) & (t_new < t)
        t[closer] = t_new[closer]
        rgb[closer] = color[closer] if color.ndim == 2 else color

    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, value in ((2, 0.0), (0, ROOM[0]), (1, ROOM[1]), (2, ROOM[2])):
            tp = (value - eye[axis]) / dirs[:, axis]
            p = eye + tp[:, None] * dirs
            if axis == 2 and value == 0.0:  # floor: 0.3 m checker tiles
                checker = (np.floor(p[:, 0] / 0.3) + np.floor(p[:, 1] / 0.3)) % 2
                color = np.where(checker[:, None] > 0, [0.6, 0.5, 0.4], [0.5, 0.42, 0.33])
            else:  # walls and ceiling: a soft vertical gradient
                shade = 0.75 + 0.08 * np.clip(p[:, 2] / ROOM[2], 0, 1)
                color = np.stack([shade, shade * 0.97, shade * 0.9], axis=1)
            hit(tp, color)
        for lo, hi, box_rgb in BOXES:
            t0 = (np.array(lo) - eye) / dirs
            t1 = (np.array(hi) - eye) / dirs
            near = np.minimum(t0, t1).max(axis=1)
            far = np.maximum(t0, t1).min(axis=1)
            hit(np.where(near <= far, near, np.inf), np.array(box_rgb))
        for centre, radius, ball_rgb in SPHERES:
            oc = eye - np.array(centre)
            a = np.einsum("ij,ij->i", dirs, dirs)
            b = 2 * dirs @ oc
            disc = b * b - 4 * a * (oc @ oc - radius**2)
            hit(np.where(disc >= 0, (-b - np.sqrt(disc)) / (2 * a), np.inf), np.array(ball_rgb))
    rng = np.random.default_rng(seed)
    rgb = np.clip(rgb + rng.normal(0.0, noise, rgb.shape), 0.0, 1.0)
    depth = np.where(np.isfinite(t), t, 0.0).reshape(height, width).astype(np.float32)
    colors = (rgb.reshape(height, width, 3) * 255).round().astype(np.uint8)
    cloud = backproject(depth, intrinsics, pose, colors, max_range=10.0)
    return cloud.points, cloud.colors


def instance_window(points: np.ndarray, n: int = 50_000) -> np.ndarray:
    """Indices of the `n` points nearest the big box's centre, in pixel order: an instance
    as a mask would cut it out of the frame."""
    centre = np.array([1.95, 1.65, 0.6])
    d = np.linalg.norm(points - centre, axis=1)
    return np.sort(np.argpartition(d, n)[:n])


def _times_ms(fn, repeats: int) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """(min, median) wall time of `repeats` calls, ms."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.min(times)), float(np.median(times))


def _cold_compile_seconds() -> float:
    """First fit and remerge in a fresh process with an empty numba cache, seconds."""
    code = (
        "import time, numpy as np\n"
        "t = time.perf_counter()\n"
        "from glmap_tools.gaussians.estimator import GaussianEstimator\n"
        "from glmap_tools.gaussians.merge import remerge\n"
        "p = np.random.default_rng(0).uniform(0, 0.2, (500, 3))\n"
        "e = GaussianEstimator()\n"
        "g = e.fit(p, np.full((500, 3), 0.5))\n"
        "remerge(g, e.config)\n"
        "print(time.perf_counter() - t)\n"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        )
    return float(out.stdout.strip().splitlines()[-1])


def redwood_frame() -> tuple[np.ndarray, np.ndarray] | None:
    """Camera-frame points and colours of the bundled Redwood living-room frame 0, if readable."""

    root = Path(__file__).resolve().parents[1] / "data" / "redwood_livingroom1_5frames"
    depth = cv2.imread(str(root / "depth" / "00000.png"), cv2.IMREAD_UNCHANGED)
    bgr = cv2.imread(str(root / "color" / "00000.jpg"))
    if depth is None or bgr is None:
        return None
    intrinsics = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)  # PrimeSense, as bundled
    cloud = backproject(
        depth_from_uint16(depth, 1000.0), intrinsics, Pose.identity(), bgr[:, :, ::-1]
    )
    return cloud.points, cloud.colors


def _cpu_ms(fn, repeats: int) -> float:  # type: ignore[no-untyped-def]
    """Median process CPU time of `repeats` calls, ms."""
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append((time.process_time() - t0) * 1e3)
    return float(np.median(times))


def reference_ratios(
    points: np.ndarray, colors: np.ndarray, voxel: float, repeats: int
) -> dict[bool, tuple[float, float]]:
    """{merge: (fast CPU ms, reference CPU ms)} of the fit of one cloud, merged and not."""
    out = {}
    for merge in (True, False):
        cfg = EstimatorConfig(voxel_size=voxel, merge=merge)
        fast = GaussianEstimator(cfg)
        fast_ms = _cpu_ms(lambda f=fast: f.fit(points, colors), repeats)
        reference = GaussianEstimator(cfg, backend="reference")
        out[merge] = (fast_ms, _cpu_ms(lambda r=reference: r.fit(points, colors), 1))
    return out


def psnr_table(points: np.ndarray, colors: np.ndarray, voxel: float) -> None:
    """Print Gaussians and same-view render PSNR per merge size cap (needs the renderer)."""
    try:
        from glmap_tools.gaussians.render import render
    except ImportError:
        print("(no glmap_tools.gaussians.render: PSNR table skipped)")
        return
    truth = synthetic_frame(noise=0.0)[1].reshape(480, 640, 3)
    camera = Intrinsics.from_fov(640, 480, 79.0)
    pose = Pose.looking_at(np.array(EYE), np.array(TARGET))
    print(f"\nmerge size cap vs same-view render PSNR at {voxel * 100:.1f} cm (exact colours):")
    print(f"{'max_merge_sigma':>16} {'Gaussians':>10} {'PSNR dB':>8}")
    for cap in ("unmerged", 1.25, 1.5, 2.0, 2.5, None):
        if cap == "unmerged":
            config = EstimatorConfig(voxel_size=voxel, merge=False)
        else:
            config = EstimatorConfig(voxel_size=voxel, max_merge_sigma=cap)  # type: ignore[arg-type]
        g = GaussianEstimator(config).fit(points, colors)
        rgb = render(g, pose, camera).rgb
        psnr = 10 * np.log10(1.0 / float(np.mean((rgb - truth) ** 2)))
        print(f"{cap!s:>16} {len(g):>10} {psnr:>8.2f}")


def _synthetic_rows(
    points: np.ndarray, colors: np.ndarray, report: Report, repeats: int
) -> np.ndarray:
    """The synthetic frame's rows (fast vs reference, merged counts, a 50k-point
    instance) and their checks; the instance's point indices."""
    window = (np.arange(180, 300)[:, None] * 640 + np.arange(240, 400)[None, :]).ravel()
    inst = instance_window(points)
    inst_points, inst_colors = points[inst], colors[inst]
    print(
        f"\n{'voxel':>6} {'voxels':>7} {'fast ms/frame':>14} {'ref ms/frame*':>14} {'ratio':>6} "
        f"{'G unmerged':>10} {'G merged':>9} {'B/G':>4} {'ms/50k inst':>12} {'G inst':>7}"
    )
    frame_ms: dict[float, float] = {}  # voxel -> median ms per frame
    instance_ms: dict[float, float] = {}  # voxel -> median ms per 50k-point instance
    for voxel in (0.015, 0.02):
        cfg = EstimatorConfig(voxel_size=voxel)
        fast = GaussianEstimator(cfg)
        merged = fast.fit(points, colors)
        unmerged = GaussianEstimator(replace(cfg, merge=False)).fit(points, colors)
        n_voxels = len(np.unique(np.floor(points / voxel).astype(np.int64), axis=0))
        fast_ms = _times_ms(lambda f=fast: f.fit(points, colors), repeats)
        reference = GaussianEstimator(cfg, backend="reference")
        ref_ms = _times_ms(lambda r=reference: r.fit(points[window], colors[window]), 1)[0]
        ref_frame_ms = ref_ms * len(points) / len(window)
        inst_ms = _times_ms(lambda f=fast: f.fit(inst_points, inst_colors), repeats)
        n_inst = len(fast.fit(inst_points, inst_colors))
        frame_ms[voxel], instance_ms[voxel] = fast_ms[1], inst_ms[1]
        print(
            f"{voxel * 100:>4.1f}cm {n_voxels:>7} {fast_ms[0]:>6.1f} /{fast_ms[1]:>6.1f} "
            f"{ref_frame_ms:>14.0f} {ref_frame_ms / fast_ms[1]:>5.0f}x {len(unmerged):>10} "
            f"{len(merged):>9} {merged.nbytes / max(len(merged), 1):>4.0f} "
            f"{inst_ms[0]:>5.2f} /{inst_ms[1]:>5.2f} {n_inst:>7}"
        )
    print(
        f"fast: min / median of {repeats} runs. * reference: one run on the central "
        f"160x120-pixel window ({len(window)} points), extrapolated by point count."
    )
    report.check("fit of a 640x480 frame at 1.5 cm, median", frame_ms[0.015], "<=", 40.0, "ms")
    for voxel, ms in instance_ms.items():
        name = f"fit of a 50k-point instance at {voxel * 100:.1f} cm, median"
        report.check(name, ms, "<=", 5.0, "ms")

    return inst


def _remerge_row(points: np.ndarray, colors: np.ndarray, inst: np.ndarray, repeats: int) -> None:
    """Remerge of the instance fitted in two frames of the same view."""
    cfg = EstimatorConfig(voxel_size=0.02)
    again, again_colors = synthetic_frame(seed=1)  # the same view, colour noise re-drawn
    both = GaussianSet.concat(
        [
            GaussianEstimator(cfg).fit(p[inst], c[inst])
            for p, c in ((points, colors), (again, again_colors))
        ]
    )
    remerge_ms = _times_ms(lambda: remerge(both, cfg), repeats)
    print(
        f"\nremerge of the instance fitted in two frames (2 cm): {len(both)} -> "
        f"{len(remerge(both, cfg))} Gaussians, {remerge_ms[0]:.2f} / {remerge_ms[1]:.2f} ms"
    )


def _redwood_rows(report: Report, repeats: int, official: type | None) -> None:
    """Redwood frame 0 at 1.5 and 2 cm, and the ratio against the reference estimator (and
    the official one, when given)."""
    real = redwood_frame()
    if real is not None:
        for voxel in (0.015, 0.02):
            cfg = EstimatorConfig(voxel_size=voxel)
            fast = GaussianEstimator(cfg)
            real_ms = _times_ms(lambda f=fast: f.fit(*real), repeats)
            unmerged = GaussianEstimator(replace(cfg, merge=False)).fit(*real)
            print(
                f"Redwood living room frame 0 ({len(real[0])} points) at {voxel * 100:.1f} cm: "
                f"{real_ms[0]:.1f} / {real_ms[1]:.1f} ms, {len(unmerged)} -> "
                f"{len(fast.fit(*real))} Gaussians"
            )
            if voxel == 0.015:
                name = "fit of Redwood frame 0 at 1.5 cm (merged), median"
                report.check(name, real_ms[1], "<=", REDWOOD_TARGET_MS, "ms")
        ratios = reference_ratios(*real, 0.015, repeats)
        print(
            f"\nRedwood frame 0 at 1.5 cm against the reference estimator (same cloud, process "
            f"CPU ms, numba threads {numba.get_num_threads()}):"
        )
        for merge, (fit_ms, reference_ms) in ratios.items():
            label = "fit + merge" if merge else "fit alone  "
            print(
                f"  {label}  fast {fit_ms:7.2f}  reference {reference_ms:8.0f}  "
                f"{reference_ms / fit_ms:5.0f}x"
            )
        merged_ms, unmerged_ms = ratios[True][0], ratios[False][0]
        print(
            f"  the merge adds {merged_ms - unmerged_ms:.2f} ms to the fit's {unmerged_ms:.2f} ms"
        )
        if official is not None:
            _official_rows(report, official, *real, 0.015, repeats)
        _stage_rows(*real, 0.015, max(repeats, 9))


def _official_rows(
    report: Report,
    official: type,
    points: np.ndarray,
    colors: np.ndarray,
    voxel: float,
    repeats: int,
) -> None:
    """Our fit against the official estimator on one cloud, alternating, in this process."""
    ours = GaussianEstimator(EstimatorConfig(voxel_size=voxel))
    unmerged = GaussianEstimator(EstimatorConfig(voxel_size=voxel, merge=False))
    # The official code's time moves by a quarter from one call to the next (966-1793 ms
    # within one process): seven rounds, so the median a ratio rests on moves less.
    rounds = max(OFFICIAL_ROUNDS, repeats // 3)
    t = official_times(
        official,
        lambda: ours.fit(points, colors),
        lambda: unmerged.fit(points, colors),
        points,
        colors,
        voxel,
        rounds,
    )
    print(
        f"\nRedwood frame 0 at {voxel * 100:.1f} cm against the official estimator "
        f"({OFFICIAL_URL}, same cloud, wall ms, medians of {rounds} alternating "
        f"rounds, numba threads {numba.get_num_threads()}):"
    )
    off, merged = t.official_gaussians
    fastest, slowest = t.official_range
    print(
        f"  official estimate(), merge off (its default)  {t.official:8.1f}  {off} Gaussians "
        f"(rounds {fastest:.0f}-{slowest:.0f})"
    )
    print(f"  official estimate(merge=True)  {t.official_merged:23.1f}  {merged} Gaussians")
    print(
        f"  ours, fit + merge {t.ours:7.2f}: {t.official / t.ours:5.1f}x the first, "
        f"{t.official_merged / t.ours:5.1f}x the second"
    )
    ratio = t.official / t.ours_unmerged
    print(f"  ours, fit alone   {t.ours_unmerged:7.2f}: {ratio:5.1f}x the first")
    report.check(
        "fit + merge against the official estimate() (merge off)",
        t.official / t.ours,
        ">=",
        OFFICIAL_TARGET_RATIO,
        "x",
    )
    report.check(
        "fit + merge against the official estimate(merge=True)",
        t.official_merged / t.ours,
        ">=",
        OFFICIAL_TARGET_RATIO,
        "x",
    )


def stage_medians(
    points: np.ndarray, colors: np.ndarray, voxel: float, repeats: int
) -> dict[str, float]:
    """Median process CPU ms of each stage of the merged fit of one cloud, in stage order."""
    config = EstimatorConfig(voxel_size=voxel)
    runs = []
    for _ in range(repeats):
        stages = StageTimes()
        pts, cols, lo = validate_cloud(points, colors, voxel)
        stages.lap("input checks")
        fit_fast(pts, cols, config, lo, stages)
        runs.append(stages.seconds)
    return {k: 1e3 * float(np.median([run[k] for run in runs])) for k in runs[0]}


def _stage_rows(points: np.ndarray, colors: np.ndarray, voxel: float, repeats: int) -> None:
    """Where the merged fit's time goes, stage by stage."""
    ms = stage_medians(points, colors, voxel, repeats)
    print(
        f"\nwhere the time goes: Redwood frame 0 at {voxel * 100:.1f} cm, merged (process CPU ms, "
        f"median of {repeats} per stage, numba threads {numba.get_num_threads()}):"
    )
    names = list(ms)
    for row in (names[:5], names[5:]):
        print("  " + "  ".join(f"{k} {ms[k]:.2f}" for k in row))
    fit = sum(ms[k] for k in FIT_STAGES)
    decisions = sum(ms[k] for k in MERGE_DECISIONS)
    total = sum(ms.values())
    print(
        f"  the fit {fit:.2f}, the merge's decisions (pairs and union) {decisions:.2f}, its "
        f"cluster sums {ms['cluster sums']:.2f}, the output {ms['output']:.2f}: {total:.2f} in all"
    )
    given = total - decisions
    print(f"  with the merge's decisions given: {given:.2f} ms, {given / total:.2f} of it all")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.bench estimator", formatter_class=HelpWithDefaults
    )
    parser.add_argument("--repeats", type=whole(1, 10_000), default=9, help="timed runs per figure")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold-compile probe")
    parser.add_argument("--psnr", action="store_true", help="also print the size-cap PSNR table")
    parser.add_argument(
        "--official",
        metavar="PATH",
        type=Path,
        help=f"a clone of {OFFICIAL_URL}: time its estimator on Redwood frame 0 too",
    )
    args = parser.parse_args(argv)
    official = load_official_estimator(args.official) if args.official is not None else None

    report = Report("bench estimator")
    t0 = time.perf_counter()
    points, colors = synthetic_frame()
    pose = Pose.looking_at(np.array(EYE), np.array(TARGET))
    depth = (points - pose.translation) @ pose.rotation[:, 2]
    print(
        f"synthetic 640x480 frame: {len(points)} points, depth 5/50/95% "
        f"{np.percentile(depth, [5, 50, 95]).round(2).tolist()} m "
        f"({time.perf_counter() - t0:.2f} s to ray-cast)"
    )
    print(
        f"numba threads: {numba.get_num_threads()}; kernels split over them only for clouds "
        f"of >= {_estimator_fast.PARALLEL_MIN_VOXELS} voxels"
    )
    t0 = time.perf_counter()
    GaussianEstimator().fit(points[:2000], colors[:2000])
    print(f"first call in this process (numba cache load): {time.perf_counter() - t0:.2f} s")
    if not args.no_cold:
        print(f"cold compile (fresh process, empty numba cache): {_cold_compile_seconds():.1f} s")

    inst = _synthetic_rows(points, colors, report, args.repeats)
    _remerge_row(points, colors, inst, args.repeats)
    _redwood_rows(report, args.repeats, official)
    if args.psnr:
        psnr_table(*synthetic_frame(noise=0.0), 0.02)
    return report.finish()
