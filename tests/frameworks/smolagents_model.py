"""A scripted smolagents `Model` that plays tests/frameworks/episode.py's episode.

smolagents has no test model. `ScriptedModel` writes one tool call per step as code for
smolagents' default agent, the CodeAgent, and reads each reply back from the printed
observation. Imports only smolagents and the standard library, so both the smolagents venv
(run_smolagents.py, the MCP adapter) and the glmap-tools venv (the in-process tools) use it.
"""

from __future__ import annotations

from typing import Any

from smolagents.models import ChatMessage, MessageRole, Model

from tests.frameworks import episode


class ScriptedModel(Model):
    """Writes one tool call per step as code; reads the reply back from the printed observation."""

    def __init__(self) -> None:
        super().__init__(model_id="scripted")
        self.replies: list[episode.Reply] = []
        self.pending: str | None = None
        self.images_seen = 0  # the most image blocks one request to the model carried

    def generate(self, messages: list[ChatMessage], *args: Any, **kwargs: Any) -> ChatMessage:
        blocks = [b for m in messages if not isinstance(m.content, str) for b in m.content or []]
        self.images_seen = max(self.images_seen, sum(b.get("type") == "image" for b in blocks))
        if self.pending is not None:
            self.replies.append((self.pending, episode.reply_json(printed(messages[-1]))))
        call = episode.next_call(self.replies)
        if call is None:
            self.pending, code = None, 'final_answer("episode over")'
        else:
            self.pending, code = call[0], f"print({call[0]}(**{call[1]!r}))"
        return ChatMessage(
            role=MessageRole.ASSISTANT, content=f"Thought: go on.\n<code>\n{code}\n</code>"
        )


def printed(message: ChatMessage) -> str:
    """The first printed JSON line of an observation message."""
    content = message.content
    text = (
        content if isinstance(content, str) else "\n".join(b.get("text", "") for b in content or [])
    )
    line = next((ln for ln in text.splitlines() if ln.startswith("{")), None)
    assert line is not None, f"no JSON reply in the observation: {text[:1000]!r}"
    return line
