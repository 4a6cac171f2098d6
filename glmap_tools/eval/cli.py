"""`glmap eval objectnav|instnav`: SR, SPL, distance to goal, steps and tool calls per agent."""

from __future__ import annotations

import argparse
from pathlib import Path

from glmap_tools.eval.spec import SPLITS, TASKS

DEFAULT_AGENTS = "glmap,glmap-instance,glmap-region,egocentric,frontier,random"


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "eval",
        help="evaluate navigation agents on the benchmark split (table with intervals)",
        description=(
            "Play the first N scenes x K episodes of a benchmark split with each agent, in "
            "parallel, and write per-episode JSON, summary.md and summary.json to --out. "
            "A rerun skips the episodes already in --out. See docs/evaluation.md."
        ),
    )
    p.add_argument("task", choices=TASKS, help="objectnav (a category) or instnav (an instance)")
    p.add_argument("--split", choices=SPLITS, required=True, help="tune for choosing settings")
    p.add_argument("--scenes", type=int, help="the first N scenes of the split (default: all)")
    p.add_argument(
        "--episodes-per-scene", type=int, help="the first K episodes of each scene (default: all)"
    )
    p.add_argument("--agents", default=DEFAULT_AGENTS, help="comma-separated agent names")
    p.add_argument(
        "--workers", type=int, default=2, help="worker processes or Ray actors (0: in process)"
    )
    p.add_argument("--ray-address", help="run on Ray: local, auto, HOST:PORT or ray://HOST:PORT")
    p.add_argument("--out", type=Path, required=True, help="results folder (resumable)")
    p.add_argument("--seed", type=int, default=0, help="base seed of every episode")
    p.add_argument("--max-steps", type=int, default=500, help="step limit of an episode")
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--resamples", type=int, default=2000, help="bootstrap resamples")
    p.add_argument("--traces", action="store_true", help="write trace + report per episode")
    p.add_argument(
        "--mix-configs", action="store_true", help="add to a folder run with other settings"
    )
    p.add_argument(
        "--summarize-only",
        action="store_true",
        help="play nothing: write the table from the episodes already finished in --out",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from glmap_tools.eval.run import run_eval
    from glmap_tools.eval.spec import EvalSpec, parse_agents

    spec = EvalSpec(
        task=args.task,
        split=args.split,
        scenes=args.scenes,
        episodes_per_scene=args.episodes_per_scene,
        agents=parse_agents(args.agents),
        seed=args.seed,
        max_steps=args.max_steps,
        embedder=args.embedder,
    )
    result = run_eval(
        spec,
        args.out,
        workers=args.workers,
        ray_address=args.ray_address,
        mix_configs=args.mix_configs,
        traces=args.traces,
        resamples=args.resamples,
        progress=not args.no_progress,
        play=not args.summarize_only,
    )
    print((result.out / "summary.md").read_text(encoding="utf-8"))
    print(
        f"played {result.ran} episodes in {result.wall_s:.0f} s "
        f"({result.episodes_per_hour:.0f} per hour), skipped {result.skipped} finished ones; "
        f"results in {result.out}"
    )
    for f in result.failures[:3]:
        last = (f.error or "").strip().splitlines()[-1:]
        print(f"FAILED {f.job.agent} on {f.job.episode_id}: {' '.join(last)}")
    if result.failures:
        print(
            f"{len(result.failures)} episodes failed (server logs: {result.out / 'logs'}); "
            "rerun the same command to retry them."
        )
        return 1
    return 0
