"""The situated QA agent: locate the situation over MCP, then answer with an MLLM or the map.

`locate_situation` (an MCP tool) gives the situated pose, the four captioned views and the
units around. The MLLM answerer sends the views with their direction annotations and the
question to an Ollama vision model (prompt `sqa_answer`, paper §3.2:
T_a = f_MLLM({(I_k, d_k)}, T_q)); the offline answerer takes the tool's `map_answer`, which
comes from the map alone and says when it cannot answer.

    python -m agents.sqa --situation "I am sitting on the bed, facing the window" \
        --question "What is to my left?" --map out/scene.glmap --model gemma3:27b
"""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.trace import ToolCallError, exit_code, prompt_set
from glmap_tools.language.llm import LLMClient
from glmap_tools.language.prompts import PromptSet
from glmap_tools.sqa.mllm_answer import (  # noqa: F401  (the agent's names since the start)
    CROP_TEXT,
    VIEW_MODES,
    VIEW_ORDER,
    SituatedAnswer,
    context_notes,
    mllm_answer,
)

# Imports inside functions stay there: the server, the runner's session and the Ollama client
# load only when the agent runs as a command (`_main`), not when its answer functions are
# imported.


@dataclass(frozen=True)
class AgentAnswer:
    """What the agent answered and from what."""

    answer: str
    confidence: float
    source: str  # "mllm" or "map"
    supported: bool
    located: dict[str, Any]


async def locate(
    client: Any, situation: str, question: str, topdown: bool = False
) -> tuple[dict[str, Any], list[bytes]]:
    """Call locate_situation; its JSON and its images (heat map, views sheet[, crop])."""
    args: dict[str, Any] = {"situation": situation, "question": question}
    if topdown:
        args["topdown"] = True
    result = await client.call_tool("locate_situation", args)
    texts = [c.text for c in result.content if c.type == "text"]
    if result.is_error:
        raise ToolCallError(f"locate_situation failed: {' '.join(texts)}")
    images = [base64.b64decode(c.data) for c in result.content if c.type == "image"]
    return json.loads(texts[0]), images


async def answer(
    client: Any,
    situation: str,
    question: str,
    llm: LLMClient | None = None,
    prompts: PromptSet | None = None,
    views: str = "four",
) -> AgentAnswer:
    """Locate `situation` and answer `question` (with `llm` when given, else from the map);
    `views` says what the MLLM sees: 'four' (the paper's views), 'topdown' or 'both'."""
    if views not in VIEW_MODES:
        raise ValueError(f"views={views!r} is not one of {list(VIEW_MODES)}.")
    info, images = await locate(client, situation, question, topdown=views != "four")
    if llm is None:
        m = info["map_answer"]
        return AgentAnswer(m["answer"], 1.0 if m["supported"] else 0.0, "map", m["supported"], info)
    crop = images[2] if views != "four" else None
    reply = await asyncio.to_thread(
        mllm_answer, llm, situation, question, info, images[1], prompts, crop, views
    )
    return AgentAnswer(reply.answer, reply.confidence, "mllm", True, info)


async def _main(args: argparse.Namespace, prompts: PromptSet | None) -> int:
    from agents.runner import open_session
    from glmap_tools.server import ServerConfig

    llm = None
    if args.model:
        from glmap_tools.language.llm import OllamaClient

        llm = OllamaClient(args.model, host=args.ollama_host, vision=True)
    config = ServerConfig(embedder=args.embedder, warm_up=False)
    async with open_session(config, server_command=args.server_command) as client:
        if args.map:
            loaded = await client.call_tool("load_map", {"name": str(args.map)})
            if loaded.is_error:
                print(loaded.content[0].text, file=sys.stderr)
                return 1
        out = await answer(client, args.situation, args.question, llm, prompts, args.views)
    print(
        json.dumps(
            {
                "answer": out.answer,
                "confidence": out.confidence,
                "source": out.source,
                "supported": out.supported,
                "pose": out.located["situation"],
            },
            indent=1,
        )
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m agents.sqa",
        description="Answer a situated question on a GLMap (MLLM through Ollama, or the map).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--situation", required=True)
    p.add_argument("--question", required=True)
    p.add_argument("--map", type=Path, help="a saved map name in the server's maps folder")
    p.add_argument("--model", default="", help="Ollama vision model; empty = map answerer")
    p.add_argument("--ollama-host", default=None)
    p.add_argument("--prompts", type=Path, default=None)
    p.add_argument("--embedder", default="minilm", choices=["minilm", "hashing"])
    p.add_argument(
        "--views",
        default="four",
        choices=list(VIEW_MODES),
        help="what the MLLM sees: the four captioned views, a top-down crop with unit ids "
        "(GPT4Scene-style), or both",
    )
    p.add_argument("--server-command", default=None)
    args = p.parse_args(argv)
    prompts = prompt_set(p, args.prompts)
    return exit_code(lambda: asyncio.run(_main(args, prompts)))


if __name__ == "__main__":
    sys.exit(main())
