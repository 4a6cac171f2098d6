"""Tool calls a chat client needs per episode, over a real MCP client session.

    python -m glmap_tools.bench calls                     # bench ObjectNav, one episode per scene
    python -m glmap_tools.bench calls --task instnav --scenes 6

The client is scripted the way docs/mcp.md ("An episode in a few calls") tells an LLM to
play: `sim_reset`; `nav_step` with 150 actions until it answers that the policy would stop;
`navigate_to` the matched unit only when `goal_unit.would_succeed` is false; `sim_step stop`.
It plays the first episode of each of the first N scenes, with MiniLM at 320x240, and checks
the median calls per episode (target <= 10) and the successes (target >= 5 of 6).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

from mcp import Client

from glmap_tools.bench._args import whole
from glmap_tools.bench.report import Report  # noqa: E402
from glmap_tools.server import ServerConfig, build_server
from glmap_tools.worlds.splits import load_split

CALLS_TARGET = 10
BUDGET = 10  # calls a client allows itself before it stops where it is


async def play(client: Any, episode: str, budget: int = BUDGET) -> tuple[dict, list[str]]:
    """One episode as the scripted client plays it: (the final status, the tools called)."""
    calls: list[str] = []

    async def call(tool: str, args: dict) -> dict:
        calls.append(tool)
        result = await client.call_tool(tool, args)
        if result.is_error:
            raise RuntimeError(f"{tool} {args}: {result.content[0].text}")
        return json.loads(result.content[0].text)

    await call("sim_reset", {"episode": episode})
    while len(calls) < budget - 2:
        walked = await call("nav_step", {"actions": 150})
        if walked["status"] != "running":
            return walked, calls
        if walked["outcome"] == "policy would stop here":
            goal = walked["goal_unit"]
            if not goal["would_succeed"]:
                await call("navigate_to", {"unit_id": goal["id"]})
            break
    return await call("sim_step", {"action": "stop"}), calls


def first_per_scene(split: str, task: str, scenes: int) -> list[str]:
    """The first episode id of each of the first `scenes` scenes of the split."""

    chosen: dict[str, str] = {}
    for be in load_split(split, task):
        chosen.setdefault(be.scene, be.episode_id)
    return [chosen[s] for s in sorted(chosen)[:scenes]]


async def _run(report: Report, args: argparse.Namespace) -> None:

    episodes = first_per_scene(args.split, args.task, args.scenes)
    counts, wins = [], 0
    with tempfile.TemporaryDirectory() as tmp:
        config = ServerConfig(maps_dir=Path(tmp), embedder=args.embedder, warm_up=False)
        async with Client(build_server(config)) as client:
            for episode in episodes:
                start = time.perf_counter()
                final, calls = await play(client, episode)
                counts.append(len(calls))
                wins += final.get("status") == "success"
                report.info(
                    f"  {episode}: {final.get('status')}, {len(calls)} calls "
                    f"({', '.join(calls)}), {time.perf_counter() - start:.0f} s"
                )
    report.check(
        f"calls per {args.task} episode, median of {len(counts)} scenes",
        statistics.median(counts),
        "<=",
        CALLS_TARGET,
    )
    report.check("episodes succeeded (share)", wins / len(counts), ">=", 5 / 6)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m glmap_tools.bench calls", description=__doc__)
    p.add_argument("--split", choices=["tune", "bench"], default="bench")
    p.add_argument("--task", choices=["objectnav", "instnav"], default="objectnav")
    p.add_argument(
        "--scenes", type=whole(1, 1000), default=12, help="the first N scenes, one episode each"
    )
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    args = p.parse_args(argv)
    report = Report("bench calls")
    asyncio.run(_run(report, args))
    return report.finish()
