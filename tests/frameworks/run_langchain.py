"""Play the scripted ObjectNav episode through langchain-mcp-adapters (runs in .ci/venvs/langchain).

    python tests/frameworks/run_langchain.py per-call|session GLMAP_MCP MAPS_DIR

per-call: the default `MultiServerMCPClient(...).get_tools()`, which starts a fresh server for
every tool call; the server is launched with `--map` so those processes share one map and
episode. session: one server for the whole episode through `client.session(...)` and
`load_mcp_tools`. The model is langchain-core's GenericFakeChatModel; its
messages come from tests/frameworks/episode.py. Prints one JSON object: the replies, how many
image blocks each tool's reply carried, the tool names and the seconds taken.
"""

from __future__ import annotations

import asyncio
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from langchain_core.language_models.fake_chat_models import GenericFakeChatModel
from langchain_core.messages import AIMessage, HumanMessage, ToolMessage
from langchain_core.utils.function_calling import convert_to_openai_tool
from langchain_mcp_adapters.client import MultiServerMCPClient
from langchain_mcp_adapters.tools import load_mcp_tools

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.frameworks import episode  # noqa: E402


def scripted(replies: list[episode.Reply]) -> Iterator[AIMessage]:
    """The fake model's messages: each tool call chosen from the replies so far."""
    while (call := episode.next_call(replies)) is not None:
        yield AIMessage(
            "", tool_calls=[{"name": call[0], "args": call[1], "id": f"c{len(replies)}"}]
        )
    yield AIMessage("episode over")


async def play(tools: list[Any]) -> dict[str, Any]:
    """A tool-calling loop: ask the model, run the tool calls it makes, hand back the results."""
    replies: list[episode.Reply] = []
    images: dict[str, int] = {}
    # What a real chat model's bind_tools sends; the fake model itself takes no tools.
    schemas = [convert_to_openai_tool(tool)["function"] for tool in tools]
    model = GenericFakeChatModel(messages=scripted(replies))
    by_name = {tool.name: tool for tool in tools}
    messages: list[Any] = [HumanMessage(f"Find the goal of {episode.EPISODE}.")]
    while True:
        answer = await model.ainvoke(messages)
        messages.append(answer)
        if not answer.tool_calls:
            break
        for call in answer.tool_calls:
            result: ToolMessage = await by_name[call["name"]].ainvoke({**call, "type": "tool_call"})
            messages.append(result)
            assert result.status != "error", f"{call['name']} failed: {result.content}"
            blocks = result.content if isinstance(result.content, list) else [result.content]
            texts = [b if isinstance(b, str) else b["text"] for b in blocks if _is_text(b)]
            replies.append((call["name"], episode.reply_json(texts[0])))
            images[call["name"]] = sum(isinstance(b, dict) and b["type"] == "image" for b in blocks)
    tools_out = {s["name"]: sorted(s["parameters"].get("properties", {})) for s in schemas}
    return {"replies": replies, "images": images, "tools": tools_out, "answer": answer.text}


def _is_text(block: Any) -> bool:
    return isinstance(block, str) or block.get("type") == "text"


async def main(mode: str, command: str, maps_dir: str) -> dict[str, Any]:
    args = ["--maps-dir", maps_dir, "--embedder", "hashing"]
    if mode == "per-call":
        args += ["--map", "langchain-test"]
    client = MultiServerMCPClient(
        {"glmap": {"transport": "stdio", "command": command, "args": args}}
    )
    start = time.perf_counter()
    if mode == "per-call":
        out = await play(await client.get_tools())
    elif mode == "session":
        async with client.session("glmap") as session:
            out = await play(await load_mcp_tools(session))
    else:
        raise SystemExit(f"mode {mode!r}: use per-call or session")
    return {**out, "seconds": round(time.perf_counter() - start, 1)}


if __name__ == "__main__":
    print(json.dumps(asyncio.run(main(*sys.argv[1:4]))))
