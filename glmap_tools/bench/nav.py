"""Navigation speed and the SR/SPL table against their targets, each MET or MISSED.

    python -m glmap_tools.bench nav                       # speed figures (tune split)
    python -m glmap_tools.bench nav --table --scenes 12 --episodes-per-scene 20

Figures (all at 320x240, MCP calls in memory):
- agent step p50: one `nav_step` call of the GLMap agent = render + integrate + value map +
  plan (target <= 150 ms);
- episodes per hour of `glmap eval` with 2 workers, full 500-step episodes of every agent
  (target >= 100);
- `navigate_to` over 5 m: a straight, free 5 m walk after `look_around` (target <= 2 s).
With --table, `glmap eval` on the split (resumable in --out) and the targets of the table:
motion (timeouts <= 10% of episodes, forward moves >= 55% of steps, median collisions <= 5
per episode, for glmap and frontier), GLMap SR >= 80% and SPL >= 0.50, the paired SR
differences glmap - frontier and glmap - egocentric above 0 with their 95% paired interval
excluding 0, and both unit kinds >= either alone. Forward moves are read from the records as
path length / step length: moves cut short count in part. Speed figures use the tune split;
the table is for the bench split.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import tempfile
from pathlib import Path
from typing import Any

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import json
import time

import anyio
import numpy as np  # noqa: E402

from agents.runner import open_session, play_episode
from glmap_tools.bench._args import whole
from glmap_tools.bench.report import Report  # noqa: E402
from glmap_tools.eval.run import run_eval
from glmap_tools.eval.spec import EvalSpec, select_episodes
from glmap_tools.eval.stats import episodes_needed
from glmap_tools.eval.table import markdown
from glmap_tools.server import ServerConfig
from glmap_tools.sim.layout_io import load_layout
from glmap_tools.sim.navgrid import build_nav_grid
from glmap_tools.worlds.splits import load_split

STEP_P50_MS = 150.0
EPISODES_PER_HOUR = 100.0
NAVIGATE_5M_S = 2.0
ALL_AGENTS = ("glmap", "glmap-instance", "glmap-region", "egocentric", "frontier", "random")


def _server_config(tmp: str, embedder: str) -> Any:

    return ServerConfig(
        maps_dir=Path(tmp) / "maps",
        embedder=embedder,  # type: ignore[arg-type]
        warm_up=False,
        compute_threads=1,
    )


async def _step_times(session: Any, episode_ids: list[str], steps: int) -> list[float]:
    """Milliseconds of every nav_step call of the GLMap agent on `episode_ids`."""

    ms: list[float] = []
    for k, eid in enumerate(episode_ids):
        reset = {"episode": eid, "max_steps": steps}
        _, client = await play_episode(session, reset, "glmap", seed=k, image_every=0)
        ms += [r.ms for r in client.records if r.tool == "nav_step"]
    return ms


def _straight_target(be: Any, metres: float) -> tuple[float, float] | None:
    """A navigable point `metres` from the start along a free straight line, if any."""

    grid = build_nav_grid(load_layout(be.layout_path))
    start = np.asarray(be.episode.start_position, np.float64)
    xs, ys = grid.cell_centers()
    pts = np.column_stack([xs.ravel(), ys.ravel()])[grid.navigable.ravel()]
    d = np.linalg.norm(pts - start, axis=1)
    for p in pts[np.argsort(np.abs(d - metres))][:400]:
        if abs(float(np.linalg.norm(p - start)) - metres) > 0.25:
            break
        if grid.segment_is_free(start, p):
            return float(p[0]), float(p[1])
    return None


async def _navigate_times(session: Any, split: str, metres: float, tries: int) -> list[dict]:
    """Time navigate_to over `metres` on the first episodes that offer a straight target."""

    out: list[dict] = []
    for be in load_split(split, "objectnav"):
        if len(out) >= tries:
            break
        target = _straight_target(be, metres)
        if target is None:
            continue
        await session.call_tool("sim_reset", {"episode": be.episode_id, "size": "320x240"})
        await session.call_tool("look_around", {})
        t0 = time.perf_counter()
        result = await session.call_tool(
            "navigate_to", {"x": target[0], "y": target[1], "max_steps": 100}
        )
        seconds = time.perf_counter() - t0
        text = result.content[0].text
        info = json.loads(text) if not result.is_error else {"outcome": f"error: {text}"}
        out.append({"episode": be.episode_id, "s": seconds, **info})
    return out


async def _speed(report: Report, args: argparse.Namespace) -> None:

    episodes = [be.episode_id for be in select_episodes("objectnav", args.split, 2, 1)]
    with tempfile.TemporaryDirectory() as tmp:
        async with open_session(_server_config(tmp, args.embedder)) as session:
            ms = await _step_times(session, episodes, args.steps)
            report.check(
                f"agent step p50 (nav_step, 320x240, {len(ms)} steps)",
                statistics.median(ms),
                "<=",
                STEP_P50_MS,
                "ms",
            )
            report.info(f"  agent step p90: {np.percentile(ms, 90):.0f} ms")
            walks = await _navigate_times(session, args.split, 5.0, 3)
    if not walks:
        report.info("navigate_to over 5 m: no straight 5 m target found in the split")
        return
    for w in walks:
        report.info(
            f"  navigate_to on {w['episode']}: {w['s']:.2f} s, {w.get('outcome')}, "
            f"{w.get('walk_steps', '?')} steps, walked {w.get('walked_m', '?')} m"
        )
    reached = [w["s"] for w in walks if w.get("outcome") == "reached"]
    report.check(
        f"navigate_to over 5 m, median of {len(walks)} walks ({len(reached)} reached)",
        statistics.median(reached) if len(reached) == len(walks) else math.inf,
        "<=",
        NAVIGATE_5M_S,
        "s",
    )


def _throughput(report: Report, args: argparse.Namespace) -> None:

    spec = EvalSpec(
        "objectnav", args.split, 1, args.throughput_episodes, ALL_AGENTS, embedder=args.embedder
    )
    with tempfile.TemporaryDirectory() as tmp:
        run = run_eval(spec, Path(tmp) / "eval", workers=2, progress=False)
    report.check(
        f"glmap eval episodes per hour, 2 workers ({run.ran} episodes x 500 steps max)",
        run.episodes_per_hour,
        ">=",
        EPISODES_PER_HOUR,
    )
    if run.failures:
        report.info(f"  {len(run.failures)} episodes failed")


def _table(report: Report, args: argparse.Namespace) -> None:

    spec = EvalSpec(
        args.task,
        args.table_split,
        args.scenes,
        args.episodes_per_scene,
        tuple(args.agents.split(",")),
        embedder=args.embedder,
    )
    run = run_eval(spec, args.out, workers=args.workers, progress=True)
    report.info(markdown(run.summary))
    report.info(
        f"played {run.ran} now ({run.episodes_per_hour:.0f} per hour), {run.skipped} from "
        f"{args.out}; failed {len(run.failures)}"
    )
    check_table_targets(report, run.summary, run.records)


def motion_figures(records: dict[str, Any], step: float = 0.25) -> dict[str, float]:
    """Timeouts (share of episodes), forward moves (share of steps: path length / `step`)
    and median collisions per episode of one agent's records (episode id -> record)."""
    rows = list(records.values())
    steps = sum(int(r["steps"]) for r in rows)
    return {
        "timeouts": float(np.mean([not r["success"] and r["steps"] >= 500 for r in rows])),
        "forward": sum(float(r["path_length"]) for r in rows) / step / max(steps, 1),
        "collisions": float(np.median([int(r["collisions"]) for r in rows])),
    }


def check_table_targets(report: Report, summary: Any, records: dict[str, Any]) -> None:
    """The navigation targets on a summary (eval.table.Summary) and its records."""
    for agent in ("glmap", "frontier"):
        if agent not in records:
            continue
        m = motion_figures(records[agent])
        report.check(f"{agent}: timeouts", 100 * m["timeouts"], "<=", 10.0, "%")
        report.check(f"{agent}: forward moves of steps", 100 * m["forward"], ">=", 55.0, "%")
        report.check(f"{agent}: median collisions per episode", m["collisions"], "<=", 5.0)
    rows = summary.rows
    if "success" in rows.get("glmap", {}):
        report.check("glmap SR", rows["glmap"]["success"].mean, ">=", 80.0, "%")
        report.check("glmap SPL", rows["glmap"]["spl"].mean, ">=", 50.0, "%")
    for other in ("frontier", "egocentric"):
        diff = summary.paired.get(("glmap", other), {}).get("success")
        if diff is None:
            continue
        report.info(
            f"paired SR glmap - {other}: {diff.mean:+.1f} [{diff.low:+.1f}, {diff.high:+.1f}]"
        )
        both = sorted(set(records.get("glmap", {})) & set(records.get(other, {})))
        if both:
            disagree = float(
                np.mean(
                    [records["glmap"][e]["success"] != records[other][e]["success"] for e in both]
                )
            )
            if disagree >= 0.06:
                report.info(
                    f"  the two disagree on {100 * disagree:.0f}% of {len(both)} episodes: a +6 "
                    f"point difference needs {episodes_needed(disagree, 0.06)} paired episodes "
                    "to show (95%, power 0.8)"
                )
        report.check(f"paired SR glmap - {other}, 95% low (> 0)", diff.low, ">=", 0.1, "points")
    for one in ("glmap-instance", "glmap-region"):
        if "success" in rows.get(one, {}) and "success" in rows.get("glmap", {}):
            report.check(
                f"SR glmap (both units) vs {one}",
                rows["glmap"]["success"].mean,
                ">=",
                rows[one]["success"].mean,
                "%",
            )


def main(argv: list[str] | None = None) -> int:

    p = argparse.ArgumentParser(prog="python -m glmap_tools.bench nav", description=__doc__)
    p.add_argument("--split", default="tune", help="split of the speed figures")
    p.add_argument(
        "--steps", type=whole(1, 100_000), default=60, help="agent steps per timed episode"
    )
    p.add_argument(
        "--throughput-episodes",
        type=int,
        default=1,
        help="episodes per agent of the episodes-per-hour figure (0: skip that figure)",
    )
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--skip-speed", action="store_true", help="only the table")
    p.add_argument("--table", action="store_true", help="also run the SR/SPL table")
    p.add_argument("--task", default="objectnav", choices=["objectnav", "instnav"])
    p.add_argument("--table-split", default="bench", choices=["tune", "bench"])
    p.add_argument("--scenes", type=int, help="table: first N scenes (default all)")
    p.add_argument("--episodes-per-scene", type=int, help="table: first K (default all)")
    p.add_argument("--workers", type=whole(0, 64), default=2, help="table: worker processes")
    p.add_argument("--agents", default=",".join(ALL_AGENTS), help="table: comma-separated")
    p.add_argument("--out", type=Path, help="table results (default out/eval/SPLIT-TASK)")
    args = p.parse_args(argv)
    if args.throughput_episodes < 0:
        p.error(f"--throughput-episodes {args.throughput_episodes}: give 0 (skip) or more")
    args.out = args.out or Path("out/eval") / f"{args.table_split}-{args.task}"

    report = Report("bench nav")
    if not args.skip_speed:
        anyio.run(_speed, report, args)
        if args.throughput_episodes > 0:
            _throughput(report, args)
    if args.table:
        _table(report, args)
    return report.finish()
