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

from pydantic import BaseModel, Field

from glmap_tools.language.llm import LLMClient, chat_structured
from glmap_tools.language.prompts import PromptSet, default_prompts

VIEW_ORDER = (
    "a 2x2 sheet: front (top left), left (top right), back (bottom left), right (bottom right)"
)


class SituatedAnswer(BaseModel):
    answer: str = Field(description="one to three words")
    confidence: float = Field(ge=0.0, le=1.0)


@dataclass(frozen=True)
class AgentAnswer:
    """What the agent answered and from what."""

    answer: str
    confidence: float
    source: str  # "mllm" or "map"
    supported: bool
    located: dict[str, Any]


async def locate(client: Any, situation: str, question: str) -> tuple[dict[str, Any], list[bytes]]:
    """Call locate_situation; its JSON and its images (heat map, views sheet)."""
    result = await client.call_tool(
        "locate_situation", {"situation": situation, "question": question}
    )
    texts = [c.text for c in result.content if c.type == "text"]
    if result.is_error:
        raise RuntimeError(f"locate_situation failed: {' '.join(texts)}")
    images = [base64.b64decode(c.data) for c in result.content if c.type == "image"]
    return json.loads(texts[0]), images


def context_notes(info: dict[str, Any]) -> str:
    """The text beside the views: what the map says is around, by direction."""
    rows = info.get("around", {}).get("nearby", [])
    by_dir: dict[str, list[str]] = {}
    for _, label, dist, _, direction in rows:
        by_dir.setdefault(direction, []).append(f"{label} ({dist} m)")
    parts = [f"{d}: {', '.join(v[:4])}" for d, v in by_dir.items()]
    return "Map notes (nearest first) - " + "; ".join(parts) + "." if parts else ""


def mllm_answer(
    llm: LLMClient,
    situation: str,
    question: str,
    info: dict[str, Any],
    views_png: bytes,
    prompts: PromptSet | None = None,
) -> SituatedAnswer:
    """T_a = f_MLLM({(I_k, d_k)}, T_q): one structured call with the views sheet."""
    prompt = (prompts or default_prompts()).get("sqa_answer")
    content = prompt.format(
        situation=situation, views=VIEW_ORDER, context=context_notes(info), question=question
    )
    value, _ = chat_structured(
        llm,
        [{"role": "user", "content": content, "images": [views_png]}],
        SituatedAnswer,
        prompt=prompt,
    )
    return value


async def answer(
    client: Any,
    situation: str,
    question: str,
    llm: LLMClient | None = None,
    prompts: PromptSet | None = None,
) -> AgentAnswer:
    """Locate `situation` and answer `question` (with `llm` when given, else from the map)."""
    info, images = await locate(client, situation, question)
    if llm is None:
        m = info["map_answer"]
        return AgentAnswer(m["answer"], 1.0 if m["supported"] else 0.0, "map", m["supported"], info)
    reply = await asyncio.to_thread(
        mllm_answer, llm, situation, question, info, images[-1], prompts
    )
    return AgentAnswer(reply.answer, reply.confidence, "mllm", True, info)


async def _main(args: argparse.Namespace) -> int:
    from agents.runner import open_session
    from glmap_tools.server import ServerConfig

    llm = None
    if args.model:
        from glmap_tools.language.llm import OllamaClient

        llm = OllamaClient(args.model, host=args.ollama_host, vision=True)
    prompts = PromptSet(args.prompts) if args.prompts else None
    config = ServerConfig(embedder=args.embedder, warm_up=False)
    async with open_session(config, server_command=args.server_command) as client:
        if args.map:
            loaded = await client.call_tool("load_map", {"name": str(args.map)})
            if loaded.is_error:
                print(loaded.content[0].text, file=sys.stderr)
                return 1
        out = await answer(client, args.situation, args.question, llm, prompts)
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
    p.add_argument("--server-command", default=None)
    return asyncio.run(_main(p.parse_args(argv)))


if __name__ == "__main__":
    sys.exit(main())
