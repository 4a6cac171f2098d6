"""Play the scripted ObjectNav episode through smolagents 1.26 (runs in .ci/venvs/smolagents).

    python tests/frameworks/run_smolagents.py GLMAP_MCP MAPS_DIR

`ToolCollection.from_mcp` (mcpadapt, mcp 1.x) over stdio and smolagents' default agent, the
CodeAgent, whose model writes Python that calls the tools. smolagents has no test model, so
`ScriptedModel` is a minimal `Model`: each step's code is one call chosen by
tests/frameworks/episode.py from the printed replies. Also records what the adapter gives the
model: whether optional arguments stay optional and what a tool returns (first block only).
Prints one JSON object.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

from mcp import StdioServerParameters
from smolagents import CodeAgent, ToolCollection
from smolagents.models import ChatMessage, MessageRole, Model, get_tool_json_schema

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.frameworks import episode  # noqa: E402


class ScriptedModel(Model):
    """Writes one tool call per step as code; reads the reply back from the printed observation."""

    def __init__(self) -> None:
        super().__init__(model_id="scripted")
        self.replies: list[episode.Reply] = []
        self.pending: str | None = None

    def generate(self, messages: list[ChatMessage], *args: Any, **kwargs: Any) -> ChatMessage:
        if self.pending is not None:
            self.replies.append((self.pending, episode.reply_json(_printed(messages[-1]))))
        call = episode.next_call(self.replies)
        if call is None:
            self.pending, code = None, 'final_answer("episode over")'
        else:
            self.pending, code = call[0], f"print({call[0]}(**{call[1]!r}))"
        return ChatMessage(
            role=MessageRole.ASSISTANT, content=f"Thought: go on.\n<code>\n{code}\n</code>"
        )


def _printed(message: ChatMessage) -> str:
    """The first printed JSON line of an observation message."""
    content = message.content
    text = (
        content if isinstance(content, str) else "\n".join(b.get("text", "") for b in content or [])
    )
    line = next((ln for ln in text.splitlines() if ln.startswith("{")), None)
    assert line is not None, f"no JSON reply in the observation: {text[:1000]!r}"
    return line


def main(command: str, maps_dir: str) -> dict[str, Any]:
    args = ["--maps-dir", maps_dir, "--embedder", "hashing"]
    server = StdioServerParameters(command=command, args=args)
    start = time.perf_counter()
    with ToolCollection.from_mcp(server, trust_remote_code=True, structured_output=False) as tools:
        model = ScriptedModel()
        agent = CodeAgent(tools=list(tools.tools), model=model, max_steps=12)
        answer = agent.run(f"Find the goal of {episode.EPISODE}.")
        schemas = {t.name: get_tool_json_schema(t)["function"] for t in tools.tools}
        reset = next(t for t in tools.tools if t.name == "sim_reset")
        shown = reset(episode=episode.EPISODE, size="160x120")  # what a direct call returns
    return {
        "answer": answer,
        "replies": model.replies,
        "tools": sorted(schemas),
        # smolagents marks an argument optional only when its input says nullable
        "required_sim_reset": schemas["sim_reset"]["parameters"]["required"],
        "reply_type": type(shown).__name__,
        "seconds": round(time.perf_counter() - start, 1),
    }


if __name__ == "__main__":
    print(json.dumps(main(*sys.argv[1:3])))
