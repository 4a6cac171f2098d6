"""`python -m glmap_tools.bench integrate`: ms per `GLMap.integrate` of a 10-instance frame."""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from glmap_tools import synthetic
from glmap_tools.bench._args import whole
from glmap_tools.bench.report import Report
from glmap_tools.cli_format import HelpWithDefaults
from glmap_tools.language.embed import Embedder, HashingEmbedder
from glmap_tools.language.minilm import default_embedder
from glmap_tools.map import GLMap, MapConfig

TARGET_MS = 150.0


class TimedEmbedder:
    """Wraps an embedder and accumulates the seconds spent embedding."""

    def __init__(self, inner: Embedder) -> None:
        self.inner = inner
        self.name, self.dim, self.default_tau_s = inner.name, inner.dim, inner.default_tau_s
        self.seconds = 0.0

    def embed(self, texts):  # type: ignore[no-untyped-def]
        start = time.perf_counter()
        try:
            return self.inner.embed(texts)
        finally:
            self.seconds += time.perf_counter() - start


def scene_with_ten_objects() -> list[synthetic.Box]:
    boxes = synthetic.floor()
    for k in range(5):  # five chairs in front of five tables, 1.5 m apart
        boxes += synthetic.chair(-3.0 + 1.5 * k, 0.0, object_id=k + 1)
        boxes += synthetic.table(-3.0 + 1.5 * k, 1.5, k + 6)
    return boxes


def main(argv: list[str] | None = None) -> int:

    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.bench integrate", formatter_class=HelpWithDefaults
    )
    parser.add_argument("--frames", type=whole(1, 10_000), default=12)
    parser.add_argument("--embedder", choices=["hashing", "minilm"], default="hashing")
    args = parser.parse_args(argv)
    report = Report("bench integrate")
    if args.embedder == "minilm":
        inner: Embedder = default_embedder()
    else:
        inner = HashingEmbedder()
    boxes = scene_with_ten_objects()
    texts = {k: ("chair", f"a wooden chair number {k}") for k in range(1, 6)}
    texts |= {k: ("table", f"a brown table number {k}") for k in range(6, 11)}
    frames = []
    for i in range(args.frames):
        eye = (-0.5 + 0.1 * i, -3.2, 1.3)
        frame, ids = synthetic.view(boxes, eye, (0.0, 0.8, 0.4), 640, 480, hfov=90.0)
        frames.append((frame, synthetic.semantics(ids, texts)))
    n_objects = np.mean([len(s.objects) for _, s in frames])
    n_points = np.mean([sum(int(o.mask.sum()) for o in s.objects) for _, s in frames])
    for label, store in (("in memory", False), ("with SQLite store", True)):
        embedder = TimedEmbedder(inner)
        with tempfile.TemporaryDirectory() as tmp:
            config = MapConfig(floor_z=0.0)
            glmap = (
                GLMap.open(Path(tmp) / "b.glmap", config, embedder=embedder)
                if store
                else GLMap(config, embedder=embedder)
            )
            glmap.integrate(*frames[0])  # warm-up: numba compile, caches
            embedder.seconds = 0.0
            times = []
            for frame, sem in frames[1:]:
                start = time.perf_counter()
                glmap.integrate(frame, sem)
                times.append(time.perf_counter() - start)
            glmap.close()
        total = np.array(times) * 1e3
        embed_ms = embedder.seconds * 1e3 / len(times)
        excl = np.median(total) - embed_ms
        print(
            f"integrate {label}: 640x480, {n_objects:.1f} objects, {n_points / 1e3:.0f}k masked "
            f"points/frame: median {np.median(total):.1f} ms (p90 {np.percentile(total, 90):.1f}),"
            f" embedding {embed_ms:.1f} ms"
        )
        report.check(f"integrate {label}, excluding embedding", excl, "<=", TARGET_MS, "ms")
        print(f"  map: {len(glmap.instances)} instances after {len(frames)} frames")
    return report.finish()
