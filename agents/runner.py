"""Run one navigation episode with a named agent through an MCP client session.

    python -m agents.runner bench/objectnav/s03-017 --agent glmap --seed 0 --out out/episode
    python -m agents.runner bench/objectnav/s03-017 --agent frontier --server-command glmap-mcp
    python -m agents.runner bench/objectnav/s03-017 --server-url http://127.0.0.1:8765/mcp

`open_session` (from `agents.session`) gives an in-memory client session on
`build_server(config)` by default (no process, no port), or a session on a stdio server
command or a streamable-HTTP URL.
`run_episode` resets the simulator on the episode (320x240 images), lets the agent play it,
and writes `trace.jsonl` (every tool call) and `report.md` / `report.html` into `out_dir`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from pydantic import BaseModel, Field

from agents.fs import region_scorer, split_agent
from agents.instnav import agent_for
from agents.report import write_report
from agents.session import AGENT_SIZE, open_session
from agents.trace import TracedClient, exit_code
from glmap_tools.errors import InvalidInputError, did_you_mean

# Imports inside functions stay there: the llm-tools agent (asyncio, the LLM client, its
# prompts), glmap_tools.server and anyio load when an episode or the command runs: `glmap`
# imports eval.spec, and through it this module, to build its parser.

AGENTS = (
    "glmap",
    "glmap-instance",
    "glmap-region",
    "egocentric",
    "frontier",
    "random",
    "llm-tools",
    "glmap+oracle-room",
    "glmap+wrong-room",
    "glmap+embedding",
    "glmap+recorded",
)
# glmap+<source>: the glmap policy with region scores f_S the client gives value_map
# (agents/fs.py: oracle-room is an upper bound from the scene's ground truth, wrong-room
# the same turned round).
# llm-tools: a chat model through Ollama calls the tools itself (agents/llm_agent.py); its
# model, server and prompt folder come from these environment variables (set by
# `glmap eval --model/--ollama-host/--prompts`). "scorer" is the f_S of the eval workers'
# in-memory servers (`glmap eval --scorer llm`), which then use the same model and prompts.
LLM_ENV = {
    "model": "GLMAP_LLM_MODEL",
    "host": "OLLAMA_HOST",
    "prompts": "GLMAP_PROMPTS",
    "scorer": "GLMAP_SCORER",
    "perception": "GLMAP_SIM_PERCEPTION",  # the workers' simulator perception (--perception)
}
DEFAULT_LLM_MODEL = "qwen3:8b"


class EpisodeResult(BaseModel):
    """The outcome of one episode played by one agent."""

    episode_id: str
    agent: str
    success: bool
    spl: float = Field(description="success weighted by path length")
    distance_to_goal: float = Field(description="geodesic metres from the end pose")
    steps: int
    path_length: float = Field(description="metres walked")
    collisions: int
    tool_calls: int = Field(description="MCP tool calls the episode took, sim_reset included")
    wall_s: float
    seed: int
    outcome: str = Field(
        default="", description="success or the kind of failure (glmap_tools.sim.outcome)"
    )
    tokens: int = Field(default=0, description="model tokens (llm-tools), prompt + output")
    turns: int = Field(default=0, description="model calls (llm-tools)")
    prompts: dict[str, str] = Field(
        default_factory=dict, description="prompt name -> name@hash (llm-tools)"
    )


def check_agent(agent: str) -> str:
    """`agent` if it is one of AGENTS.

    Raises:
        InvalidInputError: an unknown name (with the closest one suggested).
    """
    if agent not in AGENTS:
        raise InvalidInputError(
            f"agent {agent!r} is not one of {list(AGENTS)}.{did_you_mean(agent, AGENTS)}"
        )
    return agent


async def play_episode(
    client_session: Any,
    reset_args: dict[str, Any],
    agent: str,
    *,
    seed: int,
    out_dir: Path | None = None,
    actions_per_call: int = 1,
    image_every: int = 10,
    title: str = "",
) -> tuple[dict[str, Any], TracedClient]:
    """Reset with `reset_args`, let `agent` play, write the trace and report; return the result."""
    check_agent(agent)
    start_time = time.perf_counter()
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
    client = TracedClient(client_session, out_dir)
    try:
        reset = await client.call("sim_reset", {"seed": seed, "size": AGENT_SIZE, **reset_args})
        start = reset.data()
        policy, source = split_agent(agent)
        fs = region_scorer(source, str(start.get("episode", ""))) if source else None
        player = agent_for(
            start["task"],
            policy,
            seed,
            actions_per_call=actions_per_call,
            image_every=image_every,
            fs=fs,
        )
        play = await player.play(client, start)
    finally:
        client.close()
    final = play.final
    result = {
        "agent": agent,
        "success": bool(final.get("success", False)),
        "spl": float(final.get("spl", 0.0)),
        "distance_to_goal": float(final.get("distance_to_goal", float("inf"))),
        "steps": int(final["steps"]),
        "path_length": float(final.get("path_length", 0.0)),
        "collisions": int(final.get("collisions", 0)),
        "outcome": str(final.get("episode_outcome", "")),
        "tool_calls": len(client.records),
        "wall_s": round(time.perf_counter() - start_time, 3),
        "seed": seed,
    }
    if out_dir is not None:
        write_report(out_dir, title or f"{agent}: {start['goal']}", result, play, reset.images)
        (out_dir / "result.json").write_text(json.dumps(result, indent=1) + "\n")
    return result, client


async def run_episode(
    client_session: Any,
    episode_id: str,
    agent: str,
    *,
    seed: int,
    out_dir: Path | None = None,
    max_steps: int = 500,
    actions_per_call: int = 1,
    image_every: int = 10,
) -> EpisodeResult:
    """Play the benchmark episode `episode_id` with `agent` through `client_session`.

    Args:
        client_session: an open MCP client (see `open_session`).
        episode_id: a benchmark episode id, e.g. 'bench/objectnav/s03-017'.
        agent: one of AGENTS.
        seed: seeds the env reset and the agent (a seeded episode replays identically).
        out_dir: where trace.jsonl, report.md/html, result.json and images/ go; None = none.
        max_steps: the step limit.
        actions_per_call: env steps per nav_step call (map agents).
        image_every: fetch the view and the value map every this many calls (report).

    Raises:
        InvalidInputError: an unknown agent name (with the closest one suggested).
        ToolCallError: the server refused the episode (e.g. an unknown episode id).
    """
    check_agent(agent)
    if agent == "llm-tools":
        return await _run_llm_episode(client_session, episode_id, seed, out_dir, max_steps)
    result, _ = await play_episode(
        client_session,
        {"episode": episode_id, "max_steps": max_steps},
        agent,
        seed=seed,
        out_dir=out_dir,
        actions_per_call=actions_per_call,
        image_every=image_every,
        title=f"{agent} on {episode_id}",
    )
    return EpisodeResult(episode_id=episode_id, **result)


async def _run_llm_episode(
    client_session: Any, episode_id: str, seed: int, out_dir: Path | None, max_steps: int
) -> EpisodeResult:
    """The llm-tools agent on one episode (model settings from `LLM_ENV`)."""
    from agents.llm_agent import run_llm_episode
    from glmap_tools.language.llm import OllamaClient
    from glmap_tools.language.prompts import PromptSet

    model = os.environ.get(LLM_ENV["model"]) or DEFAULT_LLM_MODEL
    llm = OllamaClient(model, host=os.environ.get(LLM_ENV["host"]) or None)
    folder = os.environ.get(LLM_ENV["prompts"])
    prompts = PromptSet(folder) if folder else None
    with tempfile.TemporaryDirectory(prefix="glmap-llm-") as tmp:
        out = out_dir if out_dir is not None else Path(tmp)
        r = await run_llm_episode(
            client_session,
            episode_id,
            llm,
            seed=seed,
            out_dir=out,
            prompts=prompts,
            max_steps=max_steps,
        )
    return EpisodeResult(
        episode_id=episode_id,
        **{k: r[k] for k in EpisodeResult.model_fields if k not in ("episode_id",) and k in r},
    )


async def _main(args: argparse.Namespace) -> int:
    from glmap_tools.server import ServerConfig

    config = ServerConfig(embedder=args.embedder, warm_up=False)
    async with open_session(
        config, server_command=args.server_command, server_url=args.server_url
    ) as session:
        result = await run_episode(
            session,
            args.episode,
            args.agent,
            seed=args.seed,
            out_dir=args.out,
            max_steps=args.max_steps,
            actions_per_call=args.actions_per_call,
            image_every=args.image_every,
        )
    print(result.model_dump_json(indent=1))
    print(f"wrote {args.out / 'report.html'} and {args.out / 'trace.jsonl'}")
    return 0


def main(argv: list[str] | None = None) -> int:
    import anyio

    p = argparse.ArgumentParser(prog="python -m agents.runner", description=__doc__.split("\n")[0])
    p.add_argument("episode", help="benchmark episode id, e.g. bench/objectnav/s03-017")
    p.add_argument("--agent", default="glmap", help=f"one of {', '.join(AGENTS)}")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("out/episode"))
    p.add_argument("--max-steps", type=int, default=500)
    p.add_argument("--actions-per-call", type=int, default=1)
    p.add_argument("--image-every", type=int, default=10, help="report images every N calls")
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--server-command", help="stdio server command line instead of in-memory")
    p.add_argument("--server-url", help="streamable-HTTP server URL instead of in-memory")
    args = p.parse_args(argv)
    try:
        check_agent(args.agent)
    except InvalidInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return exit_code(lambda: int(anyio.run(_main, args) or 0))


if __name__ == "__main__":
    raise SystemExit(main())
