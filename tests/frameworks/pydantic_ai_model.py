"""pydantic-ai test models that play tests/frameworks/episode.py's episode through glmap-mcp.

Imported inside the tests of test_pydantic_ai.py, so collecting the suite does not import
pydantic-ai and fastmcp (~4 s of CPU in every worker).
"""

from __future__ import annotations

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


def stumbling_model(bad: int) -> FunctionModel:
    """A model that sends `bad` malformed calls in a row to one tool, then a good one."""
    calls = [("sim_reset", {"episode": episode.EPISODE, "size": "96x72"})]
    calls += [("sim_step", {"action": "jump"})] * bad + [("sim_step", {"action": "stop"})]

    def model(messages: list[ModelMessage], info: AgentInfo) -> ModelResponse:
        if calls:
            name, args = calls.pop(0)
            return ModelResponse(parts=[ToolCallPart(name, args)])
        return ModelResponse(parts=[TextPart("episode over")])

    return FunctionModel(model)
