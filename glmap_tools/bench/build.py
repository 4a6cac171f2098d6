"""`python -m glmap_tools.bench build`: frames/s and peak memory of `glmap build`, fast vs reference

Builds one tour folder (default: the 440-frame 640x480 tour of bench scene s00, made with
`glmap sim tour ... --step 0.15 --spin 16` on first use) with the reference pipeline and
the fast one (glmap_tools/ingest/build.py), interleaved (A B A B ...), each run in a fresh
process so that its peak memory and CPU time are its own. Prints wall time, frames/s, CPU
milliseconds per frame (all threads), peak RSS and the fast/reference ratio; the targets
are 15 frames/s and 1 GiB. `--profile` adds where a frame's time goes (ms per frame per
stage, single-threaded so that the profiler sees every stage).
"""

from __future__ import annotations

import argparse
import cProfile
import multiprocessing as mp
import os
import pstats
import statistics
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from glmap_tools.bench._args import whole
from glmap_tools.bench.report import Report
from glmap_tools.cli import main as glmap_main
from glmap_tools.cli_format import HelpWithDefaults
from glmap_tools.ingest.build import FAST, REFERENCE, BuildSettings, Pipeline, build_map

TARGET_FPS = 15.0
TARGET_RSS_MB = 1024.0
LAYOUT = "glmap_tools/data/benchmark/bench/s00/layout.json"
DEFAULT_TOUR = Path("out/bench/tour-s00")
VARIANTS = ("reference", "fast")
# Steps from the reference to the fast pipeline, to see what each one buys (--steps).
STEPS = ("blas1", "blas1+memory")


def _pipeline(variant: str) -> Any:

    return {
        "reference": REFERENCE,
        "fast": FAST,
        "blas1": Pipeline(prefetch=False, in_memory=False, blas_threads=1),
        "blas1+memory": Pipeline(prefetch=False, in_memory=True, blas_threads=1),
    }[variant]


def _run(folder: str, out: str, variant: str, frames: int | None, embedder: str) -> dict:
    """One build in this (fresh) process: its figures."""

    settings = BuildSettings(max_frames=frames, embedder=embedder)
    main_cpu = time.thread_time()
    built = build_map(
        Path(folder), Path(out), settings, overwrite=True, pipeline=_pipeline(variant)
    )
    s = built.stats
    return {
        "variant": variant,
        "frames": s.frames,
        "seconds": s.seconds,
        "cpu_s": s.cpu_s,
        "main_cpu_s": time.thread_time() - main_cpu,
        "peak_rss_mb": s.peak_rss_mb,
        "instances": s.instances,
        "regions": s.regions,
    }


def _profile(folder: str, out: str, frames: int | None, embedder: str) -> list[tuple[str, float]]:
    """(stage, ms per frame) of a single-threaded in-memory build, from cProfile."""

    settings = BuildSettings(max_frames=frames, embedder=embedder)
    profiler = cProfile.Profile()
    pipeline = Pipeline(prefetch=False, in_memory=True, blas_threads=1)
    built = profiler.runcall(
        build_map, Path(folder), Path(out), settings, overwrite=True, pipeline=pipeline
    )
    n = max(built.stats.frames, 1)
    # {(file, line, name): (calls, primitive calls, own s, cumulative s, {caller: ...})}
    stats: Any = pstats.Stats(profiler).stats  # type: ignore[attr-defined]

    def total(name: str) -> float:
        return sum(v[3] for k, v in stats.items() if k[2] == name)

    def children(parent: str) -> list[tuple[str, float]]:
        rows = []
        for key, (_, _, _, _, callers) in stats.items():
            ct = sum(c[3] for ck, c in callers.items() if ck[2] == parent)
            if ct > 0:
                rows.append((f"{parent} > {key[2]}", ct))
        return sorted(rows, key=lambda r: -r[1])[:8]

    rows = [("build_map", total("build_map")), ("load a frame (read, decode)", total("load"))]
    rows += [("integrate", total("integrate"))] + children("integrate") + children("plan_frame")
    rows += [("write the map file", total("create_from"))]
    return [(name, 1e3 * s / n) for name, s in rows]


def _tour(folder: Path) -> Path:
    if not (folder / "trajectory.log").is_file():
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        args = ["sim", "tour", LAYOUT, "--step", "0.15", "--spin", "16", "--out", str(folder)]
        glmap_main(args)
    return folder


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.bench build", formatter_class=HelpWithDefaults
    )
    parser.add_argument("--folder", type=Path, help=f"RGB-D folder (default: {DEFAULT_TOUR})")
    parser.add_argument(
        "--frames", type=whole(1, 100_000), help="the first N frames (default: all)"
    )
    parser.add_argument("--repeats", type=whole(1, 1000), default=2, help="runs of each variant")
    parser.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    parser.add_argument("--steps", action="store_true", help=f"also the steps {list(STEPS)}")
    parser.add_argument("--profile", action="store_true", help="ms per frame per stage")
    parser.add_argument("--out", type=Path, default=Path("out/bench"), help="scratch folder")
    args = parser.parse_args(argv)
    folder = str(_tour(args.folder or DEFAULT_TOUR))
    report = Report("bench build")
    variants = VARIANTS + (STEPS if args.steps else ())
    args.out.mkdir(parents=True, exist_ok=True)
    results: dict[str, list[dict]] = {v: [] for v in variants}

    def child(fn: Any, *a: Any) -> Any:

        with ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
            return pool.submit(fn, *a).result()

    child(_run, folder, str(args.out / "warm.glmap"), "fast", 3, args.embedder)  # numba caches
    for _ in range(args.repeats):
        for v in variants:
            r = child(_run, folder, str(args.out / f"{v}.glmap"), v, args.frames, args.embedder)
            results[v].append(r)
            fps, cpu_ms = r["frames"] / r["seconds"], 1e3 * r["cpu_s"] / r["frames"]
            main_ms = 1e3 * r["main_cpu_s"] / r["frames"]
            report.info(
                f"  {v:<13} {r['frames']} frames  {r['seconds']:6.1f} s  "
                f"{fps:5.1f} frames/s  CPU {cpu_ms:5.1f} ms/frame ({main_ms:5.1f} main thread)  "
                f"peak {r['peak_rss_mb']:.0f} MiB  {r['instances']} instances, "
                f"{r['regions']} regions"
            )

    def best(v: str, key: str) -> float:
        return min(r[key] for r in results[v])

    frames = results["fast"][0]["frames"]
    for v in variants:
        fps = frames / best(v, "seconds")
        cpu_ms = 1e3 * statistics.median(r["cpu_s"] for r in results[v]) / frames
        main_ms = 1e3 * statistics.median(r["main_cpu_s"] for r in results[v]) / frames
        # The main thread fuses (numba's parallel kernels also run on their own threads);
        # the read-ahead thread reads and perceives.
        report.info(
            f"{v}: best {fps:.1f} frames/s, median CPU {cpu_ms:.1f} ms/frame (main thread "
            f"{main_ms:.1f}), peak {max(r['peak_rss_mb'] for r in results[v]):.0f} MiB"
        )
    ref, fast = best("reference", "seconds"), best("fast", "seconds")
    report.info(f"fast / reference: {ref / fast:.2f}x frames/s (best of {args.repeats} each)")
    report.check("fast build, frames/s", frames / fast, ">=", TARGET_FPS, "frames/s")
    peak = max(r["peak_rss_mb"] for r in results["fast"])
    report.check("fast build, peak RSS", peak, "<=", TARGET_RSS_MB, "MiB")
    same = {(r["instances"], r["regions"]) for rs in results.values() for r in rs}
    report.info(f"instances, regions of every run: {sorted(same)} (one pair: the same map)")
    if args.profile:
        report.info("where a frame's time goes (cProfile, one thread, ms per frame):")
        for name, ms in child(
            _profile, folder, str(args.out / "p.glmap"), args.frames, args.embedder
        ):
            report.info(f"  {ms:7.1f}  {name}")
    return report.finish()
