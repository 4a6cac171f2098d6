"""`python -m glmap_tools.bench percall`: a tool call from a client that starts a server per call.

Plays what LangChain's default `get_tools()` does: every call launches `glmap-mcp --map NAME`
(the console script, default settings unless told), opens an MCP session over its stdio,
makes one call and closes it. The episode: `sim_reset` of a tune episode, then `--calls`
`sim_step`s, each in its own process. Both ways, alternating round by round in fresh map and
socket folders: plain `--map` (each process loads the map and replays the episode), and
`--map --linger` (each process relays to one background server). Prints the first call and
the median of the later ones, wall time from launch to the process's exit, and checks the
later calls with `--linger` against the handshake's own target (<= 0.5 s).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import anyio
from mcp import Client
from mcp.client.stdio import StdioServerParameters

from glmap_tools.bench._args import image_size, whole
from glmap_tools.bench.report import Report
from glmap_tools.bench.startup import server_command
from glmap_tools.cli_format import HelpWithDefaults
from glmap_tools.server.linger import lingering_servers

LATER_CALL_TARGET_S = 0.5  # as the handshake's: the relay adds no start-up of its own
EPISODE = "tune/objectnav/s03-013"


async def one_call(params: StdioServerParameters, tool: str, args: dict[str, Any]) -> float:
    """Seconds from launching the server to its exit, for one call."""
    start = time.perf_counter()
    async with Client(params) as client:
        result = await client.call_tool(tool, args)
    if result.is_error:
        raise SystemExit(f"bench percall: {tool} failed: {result.content[0].text}")  # type: ignore[union-attr]
    return time.perf_counter() - start


async def play(extra: list[str], linger: bool, calls: int, size: str) -> list[float]:
    """The seconds of each call of one episode, in fresh folders."""
    maps = Path(tempfile.mkdtemp(prefix="glmap-bench-maps-"))
    run = Path(tempfile.mkdtemp(prefix="glb"))  # a short socket folder
    args = [*server_command()[1:], "--map", "bench", "--maps-dir", str(maps), *extra]
    if linger:
        args += ["--linger", "60"]
    params = StdioServerParameters(
        command=server_command()[0], args=args, env={**os.environ, "XDG_RUNTIME_DIR": str(run)}
    )
    try:
        times = [await one_call(params, "sim_reset", {"episode": EPISODE, "size": size})]
        for _ in range(calls):
            times.append(await one_call(params, "sim_step", {"action": "turn_left"}))
        return times
    finally:
        for pid in lingering_servers(str(run)):
            os.kill(pid, signal.SIGTERM)
        shutil.rmtree(maps, ignore_errors=True)
        shutil.rmtree(run, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.bench percall", formatter_class=HelpWithDefaults
    )
    parser.add_argument(
        "--calls", type=whole(1, 10_000), default=6, help="sim_step calls after sim_reset"
    )
    parser.add_argument(
        "--rounds", type=whole(1, 1000), default=2, help="episodes per way, alternating"
    )
    parser.add_argument(
        "--size", type=image_size, default="320x240", help="the episode's image size"
    )
    parser.add_argument(
        "--server-args",
        default="",
        help="more glmap-mcp arguments, e.g. '--embedder hashing' (default: its defaults)",
    )
    args = parser.parse_args(argv)
    extra = args.server_args.split()
    report = Report("bench percall")
    report.info(f"server: {' '.join(server_command())} --map bench {' '.join(extra)}".rstrip())
    runs: dict[bool, list[list[float]]] = {False: [], True: []}
    for _ in range(args.rounds):
        for linger in (False, True):
            runs[linger].append(anyio.run(play, extra, linger, args.calls, args.size))
    later: dict[bool, float] = {}
    for linger, episodes in runs.items():
        first = statistics.median(e[0] for e in episodes)
        later[linger] = statistics.median(t for e in episodes for t in e[1:])
        way = "--map --linger 60" if linger else "--map          "
        report.info(
            f"{way}  first call (sim_reset) {first:5.2f} s, later calls (sim_step) median "
            f"{later[linger]:5.2f} s  ({args.rounds} episodes of {args.calls + 1} calls)"
        )
    report.info(f"later calls: --linger {later[False] / later[True]:.1f}x faster")
    report.check("a later call with --linger, median", later[True], "<=", LATER_CALL_TARGET_S, "s")
    return report.finish()


if __name__ == "__main__":
    sys.exit(main())
