"""pydantic-ai at its default MCP settings plays a short ObjectNav episode through glmap-mcp.

`MCPToolset` over stdio with nothing changed: it gives the server 5 s for the handshake
(issue 13 item 2). The model is pydantic-ai's FunctionModel, scripted by episode.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from fastmcp.client.transports import StdioTransport
from pydantic_ai import Agent
from pydantic_ai.mcp import MCPToolset
from pydantic_ai.messages import (
    BinaryContent,
    ModelMessage,
    ModelRequest,
    ModelResponse,
    RetryPromptPart,
    TextPart,
    ToolCallPart,
    ToolReturnPart,
)
from pydantic_ai.models.function import AgentInfo, FunctionModel

from tests.frameworks import episode

GLMAP_MCP = Path(sys.executable).parent / "glmap-mcp"


class ScriptedModel:
    """Calls the episode's tools one by one, each chosen from the replies pydantic-ai shows it."""

    def __init__(self) -> None:
        self.replies: list[episode.Reply] = []
        self.images: dict[str, int] = {}
        self.tools: list[str] = []

    def __call__(self, messages: list[ModelMessage], info: AgentInfo) -> ModelResponse:
        self.tools = [t.name for t in info.function_tools]
        last = messages[-1]
        assert isinstance(last, ModelRequest)
        for part in last.parts:
            assert not isinstance(part, RetryPromptPart), f"a tool call failed: {part.content}"
            if isinstance(part, ToolReturnPart):
                blocks = part.content if isinstance(part.content, list) else [part.content]
                data = next(b for b in blocks if isinstance(b, dict | str))
                if isinstance(data, str):
                    data = episode.reply_json(data)
                self.replies.append((part.tool_name, data))
                images = [b for b in blocks if isinstance(b, BinaryContent) and b.is_image]
                self.images[part.tool_name] = len(images)
        call = episode.next_call(self.replies)
        if call is None:
            return ModelResponse(parts=[TextPart("episode over")])
        return ModelResponse(parts=[ToolCallPart(call[0], call[1])])


@pytest.mark.slow  # starts glmap-mcp, which loads MiniLM in the background
def test_pydantic_ai_default_mcp_toolset_plays_an_objectnav_episode(tmp_path):
    model = ScriptedModel()
    server = StdioTransport(command=str(GLMAP_MCP), args=["--maps-dir", str(tmp_path)])
    agent = Agent(FunctionModel(model), toolsets=[MCPToolset(server)])  # default timeouts
    result = agent.run_sync(f"Find the {episode.EPISODE} goal.")
    assert result.output == "episode over"
    assert set(episode.TOOLS) <= set(model.tools)
    assert episode.problems(model.replies) == []
    assert model.images["sim_reset"] >= 1  # the agent's view reaches the model as an image
    assert model.images["value_map"] >= 1


def _stumbling_model(bad: int):  # type: ignore[no-untyped-def]
    """A model that sends `bad` malformed calls in a row to one tool, then a good one."""
    calls = [("sim_reset", {"episode": episode.EPISODE, "size": "96x72"})]
    calls += [("sim_step", {"action": "jump"})] * bad + [("sim_step", {"action": "stop"})]

    def model(messages: list[ModelMessage], info: AgentInfo) -> ModelResponse:
        if calls:
            name, args = calls.pop(0)
            return ModelResponse(parts=[ToolCallPart(name, args)])
        return ModelResponse(parts=[TextPart("episode over")])

    return FunctionModel(model)


@pytest.mark.slow  # starts glmap-mcp twice
def test_pydantic_ai_needs_max_retries_to_survive_two_bad_calls_in_a_row(tmp_path):
    from pydantic_ai.exceptions import UnexpectedModelBehavior

    def server() -> StdioTransport:
        args = ["--maps-dir", str(tmp_path), "--embedder", "hashing"]
        return StdioTransport(command=str(GLMAP_MCP), args=args)

    default = Agent(_stumbling_model(2), toolsets=[MCPToolset(server())])
    with pytest.raises(UnexpectedModelBehavior, match="max retries"):
        default.run_sync("Stop at once.")
    patient = Agent(_stumbling_model(2), toolsets=[MCPToolset(server(), max_retries=3)])
    assert patient.run_sync("Stop at once.").output == "episode over"
