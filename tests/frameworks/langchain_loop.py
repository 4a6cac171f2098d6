"""The tool-calling loop the LangChain tests play tests/frameworks/episode.py's episode with.

langchain-core only (no MCP adapter), so both the LangChain venv (run_langchain.py, the MCP
adapter's tools) and the glmap-tools venv (Toolset.as_langchain_tools) use it. The model is
langchain-core's GenericFakeChatModel, its tool calls chosen from the replies so far.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from langchain_core.language_models.fake_chat_models import GenericFakeChatModel
from langchain_core.messages import AIMessage, HumanMessage, ToolMessage
from langchain_core.utils.function_calling import convert_to_openai_tool

from tests.frameworks import episode


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
