"""`glmap eval objectnav|instnav|sqa|compare`: navigation (SR, SPL, distance to goal, steps,
tool calls per agent), situated QA (EM-1, EM-R1, localisation), and two runs side by side."""

from __future__ import annotations

import argparse
import hashlib
import os
from pathlib import Path

from agents.runner import DEFAULT_LLM_MODEL, LLM_ENV
from glmap_tools.eval import compare, sqa
from glmap_tools.eval.spec import SPLITS, TASKS, EvalSpec, parse_agents
from glmap_tools.language.backends import SCORERS
from glmap_tools.language.prompts import PromptSet

# Imports inside functions stay there: gymnasium, numba, scipy, sim.episodes, tqdm, trimesh,
# worlds.scene_dirs load on first use: `glmap` imports every command module to build its parser.

DEFAULT_AGENTS = "glmap,glmap-instance,glmap-region,egocentric,frontier,random"


def register(subparsers: argparse._SubParsersAction) -> None:
    top = subparsers.add_parser(
        "eval", help="evaluate agents on the benchmark split (tables with intervals)"
    )
    kinds = top.add_subparsers(dest="task", metavar="TASK", required=True)
    for task in TASKS:
        _register_nav(kinds, task)

    q = kinds.add_parser(
        "sqa",
        help="situated QA: EM-1, EM-R1 and localisation per agent",
        description=(sqa.__doc__ or "").split("\n\n")[0],
    )
    sqa.add_arguments(q)
    q.set_defaults(func=sqa.run_cli)
    c = kinds.add_parser("compare", help="two result folders side by side (prompt experiments)")
    compare.add_arguments(c)
    c.set_defaults(func=compare.run_cli)


def _register_nav(kinds: argparse._SubParsersAction, task: str) -> None:
    p = kinds.add_parser(
        task,
        help=f"{task}: SR, SPL, distance to goal, steps and tool calls per agent",
        description=(
            "Play the first N scenes x K episodes of a benchmark split with each agent, in "
            "parallel, and write per-episode JSON, summary.md and summary.json to --out. "
            "A rerun skips the episodes already in --out. See docs/evaluation.md."
        ),
    )
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--split", choices=SPLITS, help="tune for choosing settings")
    where.add_argument(
        "--scenes-dir",
        metavar="[NAME=]DIR",
        help="your own scenes: a folder of <scene>/layout.json + <scene>/<task>.json, played "
        "as the split NAME (default: the folder's name); see docs/evaluation.md",
    )
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
    p.add_argument(
        "--perception",
        choices=["auto", "gt", "detector"],
        default="auto",
        help="the simulator's perception: exact (gt), a detector's errors, or the split's own",
    )
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
    p.add_argument(
        "--complete-only",
        action="store_true",
        help="the table counts only episodes that every listed agent finished",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    g = p.add_argument_group(
        "language models (need Ollama): the llm-tools agent, and the llm scorer f_S"
    )
    g.add_argument(
        "--scorer",
        choices=SCORERS,
        default="embedding",
        help="f_S of every agent's value map: embedding cosine (offline) or llm (--model)",
    )
    g.add_argument("--model", default="", help="Ollama model, e.g. qwen3:8b")
    g.add_argument("--ollama-host", default=None, help="Ollama URL ($OLLAMA_HOST or local)")
    g.add_argument("--prompts", type=Path, default=None, help="prompt override folder")
    p.set_defaults(func=run)


def _llm_settings(args: argparse.Namespace, agents: tuple[str, ...]) -> tuple[str, str]:
    """Model and prompt-set digest of the llm-tools agent or the llm scorer; exported, with
    the scorer, to the workers' env.

    Worker processes inherit the environment (local workers; Ray workers need the same
    variables in their runtime environment).
    """

    os.environ[LLM_ENV["scorer"]] = args.scorer  # a value left in the shell must not differ
    if "llm-tools" not in agents and args.scorer != "llm":
        return "", ""
    model = args.model or DEFAULT_LLM_MODEL
    prompts = PromptSet(args.prompts)
    refs = sorted(prompts.get(n).ref for n in prompts.names())
    os.environ[LLM_ENV["model"]] = model
    if args.ollama_host:
        os.environ[LLM_ENV["host"]] = args.ollama_host
    if args.prompts:
        os.environ[LLM_ENV["prompts"]] = str(Path(args.prompts).resolve())
    digest = hashlib.sha256(" ".join(refs).encode()).hexdigest()[:12]
    return model, digest


def run(args: argparse.Namespace) -> int:
    from glmap_tools.eval.run import run_eval

    agents = parse_agents(args.agents)
    split, scenes_dir = args.split, None
    if args.scenes_dir:
        from glmap_tools.worlds.scene_dirs import parse_scene_dir

        split, scenes_dir = parse_scene_dir(args.scenes_dir)
    llm_model, prompts = _llm_settings(args, agents)

    os.environ[LLM_ENV["perception"]] = args.perception  # to the workers' servers
    spec = EvalSpec(
        task=args.task,
        split=split,
        scenes_dir=scenes_dir,
        scenes=args.scenes,
        episodes_per_scene=args.episodes_per_scene,
        agents=agents,
        seed=args.seed,
        max_steps=args.max_steps,
        embedder=args.embedder,
        scorer=args.scorer,
        perception=args.perception,
        llm_model=llm_model,
        prompts=prompts,
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
        complete_only=args.complete_only,
    )
    print((result.out / "summary.md").read_text(encoding="utf-8"))
    from glmap_tools.eval.run import run_report

    print(run_report(result))
    return 1 if result.failures else 0
