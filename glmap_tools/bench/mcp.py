"""`python -m glmap_tools.bench mcp`: tool latency through a real MCP client session.

Measures p50/p99 of find_instance and what_is_at on synthetic maps of 1k and 10k instances
(saved to a map file, opened with load_map), and of observe_frame on 640x480 frames with 10
annotated objects. find_instance is timed on queries never seen before (each embeds its
text: the figure held to the target), then on the same queries again (their vectors come
from the embedder's cache). The client talks JSON-RPC over in-memory streams (`--mode
legacy`, the default: every request and result is serialised as on a real transport) or the
direct in-process path of the 2026-07-28 protocol (`--mode auto`). `--transport http` runs
a `glmap-mcp` process on 127.0.0.1 and times find_instance over streamable HTTP on one
reused connection (where Nagle's algorithm used to add ~40 ms per call).
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import anyio
import httpx2
import numpy as np
from mcp import Client
from mcp.client.streamable_http import streamable_http_client

from glmap_tools import synthetic
from glmap_tools.app.frames import observe_arguments
from glmap_tools.bench._args import whole
from glmap_tools.bench.integrate import scene_with_ten_objects
from glmap_tools.bench.report import Report
from glmap_tools.gaussians.types import COVARIANCE_EPSILON, DEFAULT_OPACITY, GaussianSet
from glmap_tools.language.embed import Embedder, HashingEmbedder
from glmap_tools.language.minilm import default_embedder
from glmap_tools.map import GLMap
from glmap_tools.map.store import MapStore
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.server import ServerConfig, build_server

FIND_TARGET_MS = 10.0  # find_instance p50 at 10k instances (also over HTTP)
OBSERVE_TARGET_MS = 250.0  # observe_frame p50, 640x480, 10 objects
GAUSSIANS_PER_INSTANCE = 8
COLORS = [
    "red",
    "blue",
    "green",
    "white",
    "black",
    "grey",
    "brown",
    "yellow",
    "orange",
    "purple",
    "pink",
    "beige",
]
MATERIALS = [
    "wooden",
    "metal",
    "plastic",
    "leather",
    "fabric",
    "glass",
    "ceramic",
    "wicker",
    "marble",
    "velvet",
]
CATEGORIES = [
    "chair",
    "sofa",
    "table",
    "lamp",
    "bed",
    "desk",
    "shelf",
    "cabinet",
    "plant",
    "television",
    "rug",
    "mirror",
    "clock",
    "vase",
    "pillow",
    "stool",
    "bench",
    "dresser",
    "wardrobe",
    "fridge",
    "oven",
    "sink",
    "toilet",
    "bathtub",
    "painting",
]
ROOMS = [
    "kitchen",
    "bedroom",
    "living-room",
    "bathroom",
    "office",
    "hallway",
    "dining-room",
    "study",
]


def synthetic_texts(n: int, rng: np.random.Generator) -> list[str]:
    """n instance descriptions drawn from a small vocabulary."""
    c = rng.integers(len(COLORS), size=n)
    m = rng.integers(len(MATERIALS), size=n)
    k = rng.integers(len(CATEGORIES), size=n)
    return [
        f"a {COLORS[a]} {MATERIALS[b]} {CATEGORIES[d]}" for a, b, d in zip(c, m, k, strict=True)
    ]


def synthetic_map_file(path: Path, n: int, embedder: Embedder, seed: int = 0) -> float:
    """Write a map of `n` instances (and n/10 regions) spread over a floor to `path`.

    Returns the seconds spent embedding the descriptions.
    """

    rng = np.random.default_rng(seed)
    texts = synthetic_texts(n, rng)
    unique = sorted(set(texts))
    start = time.perf_counter()
    vectors = dict(zip(unique, embedder.embed(unique), strict=True))
    embed_s = time.perf_counter() - start
    side = int(np.ceil(np.sqrt(n)))
    spacing = 1.0  # metres between instance centres
    g = GAUSSIANS_PER_INSTANCE
    instances: dict[int, InstanceUnit] = {}
    for i, text in enumerate(texts):
        centre = np.array([(i % side) * spacing, (i // side) * spacing, 0.4])
        means = centre + rng.normal(0.0, 0.08, size=(g, 3))
        covs = np.tile(np.eye(3) * (4e-4 + COVARIANCE_EPSILON), (g, 1, 1))
        gaussians = GaussianSet(
            means, covs, rng.uniform(0, 1, (g, 3)), np.full(g, DEFAULT_OPACITY), np.full(g, 10)
        )
        uid = i + 1
        label = text.split()[-1]
        instances[uid] = InstanceUnit(uid, label, text, vectors[text], gaussians, 1, 0, 0)
    starts = list(range(0, n, 10))
    region_texts = [f"the {ROOMS[(s // 10) % len(ROOMS)]} corner number {s // 10}" for s in starts]
    t0 = time.perf_counter()
    region_vectors = embedder.embed(region_texts)
    embed_s += time.perf_counter() - t0
    regions: dict[int, RegionUnit] = {}
    next_id = n + 1
    for s, text, emb in zip(starts, region_texts, region_vectors, strict=True):
        members = tuple(range(s + 1, min(s + 11, n + 1)))
        regions[next_id] = RegionUnit(next_id, text, emb, members, 1, 0, 0)
        next_id += 1
    glmap = GLMap.from_units(instances, regions, next_id, embedder=embedder)
    MapStore.create_from(path, glmap).close()
    return embed_s


def percentiles(ms: list[float]) -> str:
    a = np.asarray(ms)
    return f"p50 {np.percentile(a, 50):6.1f} ms  p99 {np.percentile(a, 99):6.1f} ms  (n={len(a)})"


async def timed(client: Any, tool: str, args: dict[str, Any]) -> float:
    start = time.perf_counter()
    result = await client.call_tool(tool, args)
    elapsed = (time.perf_counter() - start) * 1e3
    if result.is_error:
        raise RuntimeError(f"{tool} failed: {result.content[0].text}")
    return elapsed


def observe_frames(count: int) -> list[dict[str, Any]]:
    """observe_frame arguments of 640x480 views of a 10-object ray-cast scene."""

    boxes = scene_with_ten_objects()
    texts = {k: ("chair", f"a wooden chair number {k}") for k in range(1, 6)}
    texts |= {k: ("table", f"a brown table number {k}") for k in range(6, 11)}
    out = []
    for i in range(count):
        eye = (-0.5 + 0.1 * i, -4.5, 1.3)
        frame, ids = synthetic.view(boxes, eye, (0.0, 1.0, 0.4), 640, 480)
        visible = sorted(int(v) for v in np.unique(ids) if v)
        objects = [{"id": v, "label": texts[v][0], "description": texts[v][1]} for v in visible]
        groups = [{"id": 1, "description": "a dining area with tables", "members": visible}]
        out.append(observe_arguments(frame, ids, objects, groups))
    return out


async def run(args: argparse.Namespace) -> int:

    report = Report("bench mcp")
    embedder: Embedder = default_embedder() if args.embedder == "minilm" else HashingEmbedder()
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as tmp:
        maps = Path(tmp)
        for n in args.sizes:
            start = time.perf_counter()
            embed_s = synthetic_map_file(maps / f"synthetic-{n}.glmap", n, embedder)
            print(
                f"built a {n}-instance map file in {time.perf_counter() - start:.1f} s "
                f"({embed_s:.1f} s embedding)"
            )
        config = ServerConfig(maps_dir=maps, embedder=args.embedder, warm_up=False)
        async with Client(build_server(config), mode=args.mode) as client:
            print(f"client session: in-memory, protocol {client.protocol_version}")
            for n in args.sizes:
                await timed(client, "load_map", {"name": f"synthetic-{n}"})
                side = int(np.ceil(np.sqrt(n)))
                queries = synthetic_texts(args.calls + 5, rng)
                # Unique queries (a random room appended) so every call embeds its text.
                queries = [f"{q} in the {ROOMS[i % len(ROOMS)]} {i}" for i, q in enumerate(queries)]
                for q in queries[:5]:  # warm-up
                    await timed(client, "find_instance", {"query": q, "top_k": 5})
                find = [
                    await timed(client, "find_instance", {"query": q, "top_k": 5})
                    for q in queries[5:]
                ]
                report.info(f"find_instance {n:>6} instances, new queries: {percentiles(find)}")
                report.check(
                    f"find_instance p50, {n} instances, new queries",
                    float(np.percentile(find, 50)),
                    "<=",
                    FIND_TARGET_MS,
                    "ms",
                )
                # The same queries again: their vectors come from the embedder's cache.
                again = [
                    await timed(client, "find_instance", {"query": q, "top_k": 5})
                    for q in queries[5:]
                ]
                report.info(
                    f"find_instance {n:>6} instances, repeated queries: {percentiles(again)}"
                )
                points = rng.uniform(0, side, size=(args.calls, 2))
                for radius in (0.25, 1.0):
                    at = [
                        await timed(
                            client, "what_is_at", {"x": float(x), "y": float(y), "radius": radius}
                        )
                        for x, y in points
                    ]
                    print(f"what_is_at    {n:>6} instances, radius {radius} m: {percentiles(at)}")
            await timed(client, "new_map", {})
            frames = observe_frames(args.frames + 1)
            await timed(client, "observe_frame", frames[0])  # warm-up: JIT, caches
            observe = [await timed(client, "observe_frame", f) for f in frames[1:]]
            report.info(f"observe_frame 640x480, 10 objects: {percentiles(observe)}")
            report.check(
                "observe_frame p50, 640x480, 10 objects",
                float(np.percentile(observe, 50)),
                "<=",
                OBSERVE_TARGET_MS,
                "ms",
            )
    return report.finish()


async def run_http(args: argparse.Namespace) -> int:
    """find_instance p50 over streamable HTTP against a spawned glmap-mcp."""

    report = Report("bench mcp --transport http")
    embedder: Embedder = default_embedder() if args.embedder == "minilm" else HashingEmbedder()
    rng = np.random.default_rng(1)
    token = "bench-token"
    with tempfile.TemporaryDirectory() as tmp:
        n = max(args.sizes)  # 0: the empty default map (times the transport alone)
        if n:
            synthetic_map_file(Path(tmp) / f"synthetic-{n}.glmap", n, embedder)
        command = (
            shlex.split(args.server_command)
            if args.server_command
            else [sys.executable, "-m", "glmap_tools.server"]
        )
        command += ["--transport", "streamable-http", "--port", "0", "--no-warm-up"]
        command += ["--embedder", args.embedder, "--maps-dir", tmp]
        env = dict(os.environ, GLMAP_MCP_TOKEN=token)
        proc = subprocess.Popen(command, env=env, stderr=subprocess.PIPE, text=True)
        try:
            assert proc.stderr is not None
            url = ""
            for line in proc.stderr:
                if line.startswith("glmap-mcp: serving "):
                    url = line.split()[-1]
                    break
            if not url:
                raise RuntimeError("glmap-mcp did not start")
            report.info(f"server: {' '.join(command[:3])} on {url}")
            http = httpx2.AsyncClient(
                headers={"Authorization": f"Bearer {token}"}, timeout=httpx2.Timeout(120.0)
            )
            async with Client(
                streamable_http_client(url, http_client=http), mode="legacy"
            ) as client:
                if n:
                    await timed(client, "load_map", {"name": f"synthetic-{n}"})
                queries = synthetic_texts(args.calls + 5, rng)
                queries = [f"{q} in the {ROOMS[i % len(ROOMS)]} {i}" for i, q in enumerate(queries)]
                for q in queries[:5]:
                    await timed(client, "find_instance", {"query": q, "top_k": 5})
                find = [
                    await timed(client, "find_instance", {"query": q, "top_k": 5})
                    for q in queries[5:]
                ]
            report.info(f"find_instance over HTTP, {n} instances: {percentiles(find)}")
            report.check(
                f"find_instance p50 over HTTP, {n} instances",
                float(np.percentile(find, 50)),
                "<=",
                FIND_TARGET_MS,
                "ms",
            )
        finally:
            proc.terminate()
            proc.wait(timeout=30)
    return report.finish()


def main(argv: list[str] | None = None) -> int:

    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench mcp")
    parser.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    parser.add_argument("--sizes", type=whole(1, 1_000_000), nargs="+", default=[1000, 10000])
    parser.add_argument(
        "--calls", type=whole(1, 100_000), default=200, help="queries per measurement"
    )
    parser.add_argument("--frames", type=whole(1, 10_000), default=12, help="observed frames")
    parser.add_argument("--mode", choices=["legacy", "auto"], default="legacy")
    parser.add_argument(
        "--transport",
        choices=["memory", "http"],
        default="memory",
        help="memory: in-process client; http: a glmap-mcp process on 127.0.0.1 "
        "(find_instance only, the largest size)",
    )
    parser.add_argument(
        "--server-command", default="", help="http: the server command (default: this Python)"
    )
    args = parser.parse_args(argv)
    if args.transport == "http":
        return int(anyio.run(run_http, args) or 0)
    return int(anyio.run(run, args) or 0)
