"""A tool-calling agent: a chat model decides every MCP call itself.

The model gets the server's own tools (read over the client session with `list_tools`
and converted to Ollama function schemas), the system prompt `tool_agent_system` and the
task, and then acts: each tool call it asks for goes through the same traced MCP client
session every other agent uses; results come back as tool messages (with their images
when the model has vision). The loop is bounded by turns and by tokens; running out
of either stops the episode where the agent stands. Every model request and reply, and
every tool call and result, lands in `transcript.jsonl`.

    python -m agents.llm_agent bench/objectnav/s00-000 --model qwen3:8b --out out/llm
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.objectnav import Play, StepRecord
from agents.session import AGENT_SIZE, open_session
from agents.trace import TracedClient, exit_code, prompt_set
from glmap_tools.errors import InvalidInputError, did_you_mean
from glmap_tools.language.llm import LLMClient, OllamaClient
from glmap_tools.language.prompts import PromptSet, default_prompts
from glmap_tools.language.transcript import Transcript
from glmap_tools.server import ServerConfig

# What a navigating agent may call; map admin tools (new_map, load_map, export_ply ...)
# and sim_reset (the runner starts the episode) stay out of its hands.
NAV_TOOLS = (
    "look_around",
    "value_map",
    "frontiers",
    "navigate_to",
    "sim_step",
    "find_instance",
    "find_region",
    "what_is_at",
    "describe_unit",
    "render_view",
    "map_summary",
)
HIDDEN_ARGUMENTS = ("session",)
MAX_RESULT_CHARS = 4000  # of one tool result's text sent back to the model
MAX_NUDGES = 3  # replies without a tool call in a row before the agent gives up


def ollama_tools(tools: Sequence[Any], allowed: Sequence[str] = NAV_TOOLS) -> list[dict]:
    """MCP tools (from `list_tools`) as Ollama function-tool schemas, in `allowed` order.

    The `session` argument is hidden: the agent works in its client's default session.
    """
    by_name = {t.name: t for t in tools}
    missing = [name for name in allowed if name not in by_name]
    if missing:
        raise InvalidInputError(
            f"the server offers no tool {missing}; its tools: {sorted(by_name)}."
        )
    out = []
    for name in allowed:
        tool = by_name[name]
        schema = json.loads(json.dumps(tool.input_schema or {"type": "object"}))
        props = schema.get("properties", {})
        for hidden in HIDDEN_ARGUMENTS:
            props.pop(hidden, None)
        if "required" in schema:
            schema["required"] = [r for r in schema["required"] if r not in HIDDEN_ARGUMENTS]
        out.append(
            {
                "type": "function",
                "function": {
                    "name": name,
                    "description": (tool.description or "").strip(),
                    "parameters": schema,
                },
            }
        )
    return out


@dataclass
class Budget:
    """Bounds of one episode: model turns and tokens (prompt + output)."""

    max_turns: int = 40
    max_tokens: int = 400_000
    turns: int = 0
    tokens: int = 0
    notes: list[str] = field(default_factory=list)

    def spent(self) -> str | None:
        if self.turns >= self.max_turns:
            return f"turn budget of {self.max_turns} used"
        if self.tokens >= self.max_tokens:
            return f"token budget of {self.max_tokens} used"
        return None


def _task_text(start: dict[str, Any]) -> str:
    if start.get("task") == "instnav":
        return f"find the one object described as: {start['goal']!r}, and stop within 1 m of it"
    return f"find any {start['goal']!r} and stop within 1 m of it"


def _episode_status(texts: list[str]) -> dict[str, Any] | None:
    """The simulator status in a tool result's first text, if it carries one."""
    if not texts:
        return None
    try:
        data = json.loads(texts[0])
    except json.JSONDecodeError:
        return None
    return data if isinstance(data, dict) and "status" in data and "steps" in data else None


class LLMToolAgent:
    """Plays an episode already started with sim_reset, with a model choosing every call.

    Args:
        llm: the model (an `LLMClient`, e.g. `OllamaClient("qwen3:8b", vision=True)`).
        prompts: prompt set (uses `tool_agent_system`).
        budget: turn and token bounds.
        transcript: where model requests/replies and tool calls/results are written.
        allowed: the tools the model gets.
    """

    def __init__(
        self,
        llm: LLMClient,
        prompts: PromptSet | None = None,
        *,
        budget: Budget | None = None,
        transcript: Transcript | None = None,
        allowed: Sequence[str] = NAV_TOOLS,
    ) -> None:
        self.llm = llm
        self.prompts = prompts or default_prompts()
        self.budget = budget or Budget()
        self.transcript = transcript or Transcript()
        self.allowed = tuple(allowed)

    async def _llm_chat(self, messages: list[dict], tools: list[dict], prompt: Any) -> Any:
        return await asyncio.to_thread(self.llm.chat, messages, tools=tools, prompt=prompt)

    async def play(
        self, client: TracedClient, start: dict[str, Any], start_images: Sequence[bytes] = ()
    ) -> Play:
        """Let the model act until the episode ends or a budget runs out."""
        listed = await client.client.list_tools()
        tools = ollama_tools(listed.tools, self.allowed)
        system = self.prompts.get("tool_agent_system")
        messages: list[dict[str, Any]] = [
            {
                "role": "system",
                "content": system.format(task=_task_text(start), max_turns=self.budget.max_turns),
            },
            {
                "role": "user",
                "content": "The episode has started. Status: " + json.dumps(start),
                "images": list(start_images) if self.llm.vision else None,
            },
        ]
        self.transcript.write(
            "note", event="episode_start", goal=start.get("goal"), prompt=system.ref
        )
        steps: list[StepRecord] = []
        status, nudges = start, 0
        while status.get("status") == "running":
            reason = self.budget.spent()
            if reason:
                self.transcript.write("note", event="budget", reason=reason)
                self.budget.notes.append(reason)
                record = await client.call("sim_step", {"action": "stop"})
                status = _episode_status(record.texts) or status
                break
            reply = await self._llm_chat(messages, tools, system)
            self.budget.turns += 1
            self.budget.tokens += reply.prompt_tokens + reply.output_tokens
            assistant: dict[str, Any] = {"role": "assistant", "content": reply.content}
            if reply.tool_calls:
                assistant["tool_calls"] = [
                    {"function": {"name": c.name, "arguments": c.arguments}}
                    for c in reply.tool_calls
                ]
            messages.append(assistant)
            if not reply.tool_calls:
                nudges += 1
                if nudges >= MAX_NUDGES:
                    self.budget.notes.append("the model stopped calling tools")
                    self.transcript.write("note", event="no_tool_calls", turns=nudges)
                    record = await client.call("sim_step", {"action": "stop"})
                    status = _episode_status(record.texts) or status
                    break
                messages.append(
                    {
                        "role": "user",
                        "content": "Call one of the tools. When the goal is within 1 m, call "
                        'sim_step with action "stop".',
                    }
                )
                continue
            nudges = 0
            status = await self._answer_calls(client, reply.tool_calls, messages, steps, status)
        self.transcript.write("note", event="episode_end", status=status)
        return Play(start, status, steps)

    async def _answer_calls(
        self,
        client: TracedClient,
        calls: Sequence[Any],
        messages: list[dict[str, Any]],
        steps: list[StepRecord],
        status: dict[str, Any],
    ) -> dict[str, Any]:
        """Make the model's tool calls in order, each result a `tool` message; a call that
        moved the agent adds a step. Stops at the call that ends the episode; the status."""
        for call in calls:
            content, images, new_status = await self._call(client, call.name, call.arguments)
            messages.append(
                {
                    "role": "tool",
                    "tool_name": call.name,
                    "content": content,
                    "images": images if (images and self.llm.vision) else None,
                }
            )
            if new_status is not None:
                status = new_status
                steps.append(
                    StepRecord(
                        int(status["steps"]),
                        call.name,
                        list(status.get("position", [0.0, 0.0])),
                        float(status.get("heading_deg", 0.0)),
                        reason=json.dumps(call.arguments)[:200],
                        call=len(client.records),
                    )
                )
            if status.get("status") != "running":
                break
        return status

    async def _call(
        self, client: TracedClient, name: str, arguments: dict[str, Any]
    ) -> tuple[str, list[bytes], dict[str, Any] | None]:
        """Run one tool call the model asked for; (text for the model, images, status)."""
        self.transcript.write("tool_call", tool=name, arguments=arguments)
        if name not in self.allowed:
            text = (
                f"error: there is no tool {name!r}.{did_you_mean(name, self.allowed)} "
                f"Tools: {list(self.allowed)}."
            )
            self.transcript.write("tool_result", tool=name, is_error=True, texts=[text])
            return text, [], None
        args = {k: v for k, v in arguments.items() if k not in HIDDEN_ARGUMENTS}
        record = await client.call(name, args)
        text = "\n".join(record.texts)
        if len(text) > MAX_RESULT_CHARS:
            text = text[:MAX_RESULT_CHARS] + " ... (cut)"
        if record.is_error:
            text = "error: " + text
        images = []
        if client.out_dir is not None:
            images = [(client.out_dir / p).read_bytes() for p in record.images]
        self.transcript.write(
            "tool_result",
            tool=name,
            is_error=record.is_error,
            texts=record.texts,
            image_files=record.images,
        )
        return text, images, None if record.is_error else _episode_status(record.texts)


async def run_llm_episode(
    client_session: Any,
    episode_id: str,
    llm: LLMClient,
    *,
    seed: int,
    out_dir: Path,
    prompts: PromptSet | None = None,
    budget: Budget | None = None,
    max_steps: int = 500,
    image_size: str = "",
) -> dict[str, Any]:
    """Play benchmark episode `episode_id` with a tool-calling model; return the result.

    Writes `trace.jsonl` (tool calls), `transcript.jsonl` (model and tool events) and
    `result.json` into `out_dir`. `image_size`: the simulator's images, default the
    agents' 320x240.
    """
    t0 = time.perf_counter()
    out_dir.mkdir(parents=True, exist_ok=True)
    client = TracedClient(client_session, out_dir)
    transcript = Transcript(out_dir / "transcript.jsonl")
    if getattr(llm, "transcript", False) is None:  # the model's calls go to the same file
        llm.transcript = transcript  # type: ignore[attr-defined]
    agent = LLMToolAgent(llm, prompts, budget=budget, transcript=transcript)
    try:
        reset = await client.call(
            "sim_reset",
            {
                "episode": episode_id,
                "seed": seed,
                "size": image_size or AGENT_SIZE,
                "max_steps": max_steps,
            },
        )
        start = reset.data()
        start_images = [(out_dir / p).read_bytes() for p in reset.images]
        play = await agent.play(client, start, start_images)
    finally:
        client.close()
        transcript.close()
    final = play.final
    result = {
        "episode_id": episode_id,
        "agent": "llm-tools",
        "model": llm.model,
        "success": bool(final.get("success", False)),
        "spl": float(final.get("spl", 0.0)),
        "distance_to_goal": float(final.get("distance_to_goal", float("inf"))),
        "steps": int(final.get("steps", 0)),
        "path_length": float(final.get("path_length", 0.0)),
        "collisions": int(final.get("collisions", 0)),
        "tool_calls": len(client.records),
        "turns": agent.budget.turns,
        "tokens": agent.budget.tokens,
        "notes": agent.budget.notes,
        "prompts": {"tool_agent_system": agent.prompts.get("tool_agent_system").ref},
        "wall_s": round(time.perf_counter() - t0, 3),
        "seed": seed,
    }
    (out_dir / "result.json").write_text(json.dumps(result, indent=1) + "\n")
    return result


async def _main(args: argparse.Namespace, prompts: PromptSet | None) -> int:
    llm = OllamaClient(args.model, host=args.ollama_host, vision=args.vision)
    config = ServerConfig(embedder=args.embedder, warm_up=False)
    async with open_session(
        config, server_command=args.server_command, server_url=args.server_url
    ) as session:
        result = await run_llm_episode(
            session,
            args.episode,
            llm,
            seed=args.seed,
            out_dir=args.out,
            prompts=prompts,
            budget=Budget(args.max_turns, args.max_tokens),
            max_steps=args.max_steps,
        )
    print(json.dumps(result, indent=1))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m agents.llm_agent",
        description="Play one benchmark episode with an Ollama model that calls the tools.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("episode", help="benchmark episode id, e.g. bench/objectnav/s00-000")
    p.add_argument("--model", default="qwen3:8b", help="Ollama model tag")
    p.add_argument("--ollama-host", default=None, help="Ollama URL ($OLLAMA_HOST or local)")
    p.add_argument("--vision", action="store_true", help="send tool images to the model")
    p.add_argument("--prompts", type=Path, default=None, help="prompt override folder")
    p.add_argument("--max-turns", type=int, default=40)
    p.add_argument("--max-tokens", type=int, default=400_000)
    p.add_argument("--max-steps", type=int, default=500)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--embedder", default="minilm", choices=["minilm", "hashing"])
    p.add_argument("--server-command", default=None, help="stdio server command line")
    p.add_argument("--server-url", default=None, help="streamable-HTTP server URL")
    p.add_argument("--out", type=Path, default=Path("out/llm_agent"))
    args = p.parse_args(argv)
    prompts = prompt_set(p, args.prompts)
    return exit_code(lambda: asyncio.run(_main(args, prompts)))


if __name__ == "__main__":
    sys.exit(main())
