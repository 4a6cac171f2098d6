"""`python -m glmap_tools.bench lock`: how long one observe_frame keeps its map locked.

The worst case within the server's documented limits: a frame with the most objects
(`MAX_OBJECTS`) and groups (`MAX_GROUPS`), every description at the longest allowed
(`MAX_DESCRIPTION_CHARS`) and built to be expensive to merge (many short sentences of
rare made-up words, so nothing is in the embedder's cache), seen again and again so every
text buffer overflows and is merged on every sighting.

The lock-hold time is measured from outside, as another client of the map feels it: while
each observe_frame runs, a second task on the same session calls what_is_at in a loop; the
longest of those calls is how long the map stayed locked (plus one cheap call). Target:
LOCK_TARGET_S.

The same frame must not hold other sessions either (issue 27 item 1): they share the
server's text embedder. A second session of the same server (the tools run in-process, as
glmap-mcp runs them, on one app state), on its own map, calls find_instance with a query
never seen before (so it runs the model) in a loop meanwhile; its longest call is the
cross-session wait. Target: LOCK_TARGET_S.

`--refusals` times how fast the frames of issue 12 item 2 that would poison a map (a pose
1e300 m away, hfov 179.999 deg, fx = 1e-300, ...) are refused; `--merge-scaling` times
one extractive merge per buffer length, to show it costs about linear in the buffer.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path
from typing import Any

import anyio
import numpy as np
from mcp import Client

from glmap_tools.app.frames import observe_arguments
from glmap_tools.app.inputs import MAX_GROUPS, MAX_OBJECTS
from glmap_tools.bench._args import MAX_SIDE, whole
from glmap_tools.bench.report import Report, load_average
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.text_merger import DELIMITER, MAX_DESCRIPTION_CHARS, ExtractiveTextMerger
from glmap_tools.server import ServerConfig, build_server
from glmap_tools.toolset import Toolset

LOCK_TARGET_S = 2.0
SYLLABLES = ["zor", "bex", "qua", "vil", "mur", "tak", "pho", "gry", "lun", "dex", "kiv", "sno"]


def tiled_frame(objects: int, width: int, height: int) -> tuple[Any, np.ndarray]:
    """A camera 2 m in front of a wall split into `objects` tiles, one object per tile.

    Returns:
        (RGBDFrame, ids [H, W] int32 with tile k holding id k + 1).
    """

    cols = int(np.ceil(np.sqrt(objects)))
    rows = int(np.ceil(objects / cols))
    v, u = np.mgrid[0:height, 0:width]
    tile = (v * rows // height) * cols + (u * cols // width)
    ids = np.where(tile < objects, tile + 1, 0).astype(np.int32)
    rng = np.random.default_rng(0)
    palette = rng.integers(30, 226, size=(objects + 1, 3), dtype=np.uint8)
    rgb = palette[ids]
    depth = np.full((height, width), 2.0, np.float32)
    intrinsics = Intrinsics.from_fov(width, height, 79.0)
    pose = Pose.looking_at(np.array([0.0, -2.0, 1.2]), np.array([0.0, 0.0, 1.2]))
    return RGBDFrame(rgb, depth, intrinsics, pose), ids


def costly_description(rng: np.random.Generator, pool: list[str], max_chars: int) -> str:
    """Short sentences of words drawn from `pool`, up to `max_chars` characters."""
    out: list[str] = []
    size = 0
    while True:
        words = rng.choice(pool, size=int(rng.integers(2, 5)))
        sentence = " ".join(words) + "."
        if size + len(sentence) + 1 > max_chars:
            return " ".join(out)
        out.append(sentence)
        size += len(sentence) + 1


def made_up_words(rng: np.random.Generator, n: int) -> list[str]:
    """`n` distinct nonsense words of 3-4 syllables (several word pieces each)."""
    words: set[str] = set()
    while len(words) < n:
        words.add("".join(rng.choice(SYLLABLES, size=int(rng.integers(3, 5)))))
    return sorted(words)


async def observed_with_probe(
    tools: Any, call: dict[str, Any], other: str
) -> tuple[float, list[float], Any, list[float]]:
    """Call observe_frame while another task calls what_is_at on the same map in a loop and
    a third calls find_instance, with a query never seen before, in session `other`.

    Returns:
        (observe_frame seconds, seconds of each what_is_at call, the observe_frame result,
        seconds of each find_instance call of the other session).
    """

    waits: list[float] = []
    across: list[float] = []
    done = anyio.Event()
    out: dict[str, Any] = {}

    async def observe() -> None:
        start = time.perf_counter()
        try:
            out["res"] = await tools.acall("observe_frame", call)
        finally:
            out["s"] = time.perf_counter() - start
            done.set()

    async def probe() -> None:
        await anyio.sleep(0.05)
        while not done.is_set():
            start = time.perf_counter()
            await tools.acall("what_is_at", {"x": 0.0, "y": 0.0, "radius": 0.1})
            waits.append(time.perf_counter() - start)
            await anyio.sleep(0.05)

    async def probe_other() -> None:
        await anyio.sleep(0.05)
        while not done.is_set():
            query = f"a {SYLLABLES[len(across) % 12]} lamp number {len(across)} {time.time()}"
            start = time.perf_counter()
            await tools.acall("find_instance", {"query": query, "top_k": 1, "session": other})
            across.append(time.perf_counter() - start)
            await anyio.sleep(0.05)

    async with anyio.create_task_group() as tg:
        tg.start_soon(observe)
        tg.start_soon(probe)
        tg.start_soon(probe_other)
    return out["s"], waits, out["res"], across


async def run(args: argparse.Namespace) -> int:

    report = Report("bench lock")
    frame, ids = tiled_frame(args.objects, args.width, args.height)
    rng = np.random.default_rng(args.seed)
    pools = [made_up_words(rng, 300) for _ in range(args.objects)]
    report.info(
        f"observe_frame {args.width}x{args.height}, {args.objects} objects and "
        f"{args.groups} groups, descriptions of {args.chars} characters, "
        f"{args.sightings} sightings, embedder {args.embedder}"
    )
    worst = worst_other = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        config = ServerConfig(maps_dir=Path(tmp), embedder=args.embedder, warm_up=False)
        # One server (one embedder, as glmap-mcp has), two sessions, each on its own map.
        with Toolset(config) as tools:
            other = tools.state.registry.start_session().handle
            # Warm-up (embedder load, JIT) on a one-object frame, then a fresh map.
            one = [{"id": 1, "label": "thing", "description": "a thing"}]
            await tools.acall("observe_frame", observe_arguments(frame, ids == 1, one))
            await tools.acall(
                "observe_frame", {**observe_arguments(frame, ids == 1, one), "session": other}
            )
            await tools.acall("new_map", {})
            for sighting in range(args.sightings):
                objects = [
                    {
                        "id": k + 1,
                        "label": f"thing {k + 1}",
                        "description": costly_description(rng, pools[k], args.chars),
                    }
                    for k in range(args.objects)
                ]
                groups = [
                    {
                        "id": g + 1,
                        "description": costly_description(rng, pools[g], args.chars),
                        "members": [g + 1, (g + args.groups) % args.objects + 1],
                    }
                    for g in range(args.groups)
                ]
                call = observe_arguments(frame, ids, objects, groups)
                observe_s, waits, res, across = await observed_with_probe(tools, call, other)
                update = res.report
                held = max(waits, default=0.0)
                worst = max(worst, held)
                held_other = max(across, default=0.0)
                worst_other = max(worst_other, held_other)
                report.info(
                    f"sighting {sighting + 1}: observe_frame {observe_s:.2f} s, "
                    f"{len(update.instances_merged)} instances and "
                    f"{len(update.regions_merged)} regions merged; longest wait of a "
                    f"concurrent what_is_at {held:.2f} s ({len(waits)} calls), of a "
                    f"find_instance in another session {held_other:.2f} s ({len(across)} "
                    f"calls, median {float(np.median(across or [0.0])):.2f} s); {load_average()}"
                )
    report.check("lock hold, worst sighting", worst, "<=", LOCK_TARGET_S, "s")
    report.check("another session's wait, worst sighting", worst_other, "<=", LOCK_TARGET_S, "s")
    return report.finish()


# Frames the server must refuse quickly (issue 12 item 2): (case, pose offset, intrinsics).
POISON: list[tuple[str, tuple[float, float, float], dict[str, float] | None]] = [
    ("pose translated 1e300 m", (1e300, 0.0, 0.0), None),
    ("second frame 900 m away", (-900.0, 0.0, 0.0), None),
    ("hfov 179.999 deg", (0.0, 0.0, 0.0), {"hfov_deg": 179.999}),
    ("hfov 179.9999999 deg", (0.0, 0.0, 0.0), {"hfov_deg": 179.9999999}),
    ("fx = 1e-300", (0.0, 0.0, 0.0), {"fx": 1e-300, "fy": 40.0, "cx": 31.5, "cy": 23.5}),
    ("cx = 1e300", (0.0, 0.0, 0.0), {"fx": 40.0, "fy": 40.0, "cx": 1e300, "cy": 23.5}),
]


async def run_refusals(args: argparse.Namespace) -> int:
    """Time each poisoning 64x48 frame of POISON after one good frame, and map_summary after."""

    report = Report("bench lock --refusals")
    frame, ids = tiled_frame(4, 64, 48)
    objects = [{"id": k, "label": "thing", "description": f"thing {k}"} for k in range(1, 5)]
    good = observe_arguments(frame, ids, objects)
    worst, accepted = 0.0, 0
    with tempfile.TemporaryDirectory() as tmp:
        config = ServerConfig(maps_dir=Path(tmp), embedder="hashing", warm_up=False)
        async with Client(build_server(config)) as client:
            await client.call_tool("observe_frame", good)
            for case, offset, intrinsics in POISON:
                call = {**good, "pose": {**good["pose"]}}
                call["pose"]["matrix"] = [list(r) for r in good["pose"]["matrix"]]
                for k in range(3):
                    call["pose"]["matrix"][k][3] += offset[k]
                if intrinsics is not None:
                    call["intrinsics"] = intrinsics
                rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
                start = time.perf_counter()
                res = await client.call_tool("observe_frame", call)
                took = time.perf_counter() - start
                summary = await client.call_tool("map_summary", {})
                grew = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss) / 1024
                worst = max(worst, took)
                verdict = "refused" if res.is_error else "ACCEPTED"
                after = "map_summary fails" if summary.is_error else "map_summary ok"
                report.info(
                    f"{case}: {verdict} in {took * 1e3:.0f} ms, peak memory +{grew:.0f} MiB, "
                    f"{after}: {getattr(res.content[0], 'text', '')[:110]}"
                )
                accepted += not res.is_error
    report.check("poisoning frames accepted", accepted, "<=", 0)
    report.check("slowest answer to a poisoning frame", worst, "<=", 0.5, "s")
    return report.finish()


def run_merge_scaling(args: argparse.Namespace) -> int:
    """Time one extractive merge per buffer length (hashing embedder: the algorithm alone)."""

    report = Report("bench lock --merge-scaling")
    rng = np.random.default_rng(args.seed)
    pool = made_up_words(rng, 4000)
    merger = ExtractiveTextMerger(HashingEmbedder())
    per_word: dict[int, float] = {}
    for words in (1000, 2000, 4000, 8000):
        descriptions = [costly_description(rng, pool, 1000) for _ in range(words // 100)]
        buffer = DELIMITER.join(descriptions)
        n = len(buffer.split())
        start = time.perf_counter()
        merger.merge([buffer], 300)
        took = time.perf_counter() - start
        per_word[words] = took / n
        report.info(
            f"merge of a {n}-word buffer: {took * 1e3:.0f} ms ({took / n * 1e6:.0f} us/word)"
        )
    growth = per_word[8000] / per_word[1000]
    report.check("time per word, 8k-word vs 1k-word buffer", growth, "<=", 1.5)
    return report.finish()


def main(argv: list[str] | None = None) -> int:

    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench lock")
    parser.add_argument("--objects", type=whole(1, MAX_OBJECTS), default=MAX_OBJECTS)
    parser.add_argument("--groups", type=whole(0, MAX_GROUPS), default=MAX_GROUPS)
    parser.add_argument(
        "--chars", type=whole(1, MAX_DESCRIPTION_CHARS), default=MAX_DESCRIPTION_CHARS
    )
    parser.add_argument("--sightings", type=whole(1, 1000), default=3)
    parser.add_argument("--width", type=whole(1, MAX_SIDE), default=640)
    parser.add_argument("--height", type=whole(1, MAX_SIDE), default=480)
    parser.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--refusals", action="store_true", help="time the refusal of poisoning frames instead"
    )
    parser.add_argument(
        "--merge-scaling", action="store_true", help="time merges of growing buffers instead"
    )
    args = parser.parse_args(argv)
    if args.merge_scaling:
        return run_merge_scaling(args)
    return int(anyio.run(run_refusals if args.refusals else run, args) or 0)
