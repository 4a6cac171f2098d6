"""A traced MCP client: every tool call goes to a JSONL trace, its images to files.

One line per call: `{"call", "tool", "arguments", "is_error", "texts", "images", "ms"}`.
Everything but `ms` is a function of the episode and its seed, so two runs of a seeded
episode give the same trace less `ms` (the replay test holds this).
"""

from __future__ import annotations

import argparse
import base64
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.prompts import PromptSet


class ToolCallError(RuntimeError):
    """A tool call the agent relies on came back as an MCP tool error."""


def exit_code(run: Callable[[], int]) -> int:
    """`run()`'s exit code; a tool's refusal, raised alone or out of task groups, is printed
    as one error line (it says what to fix) and exits 2, without a traceback."""
    refused: list[ToolCallError] = []
    try:
        return run()
    except* ToolCallError as group:
        refused.extend(_leaves(group))
    for refusal in refused:
        print(f"error: {refusal}", file=sys.stderr)
    return 2


def prompt_set(parser: argparse.ArgumentParser, folder: Path | None) -> PromptSet | None:
    """The `--prompts` folder's prompts (None: the defaults); a missing folder or a bad
    prompt file is the parser's usage error (one line, exit 2)."""
    try:
        return PromptSet(folder) if folder else None
    except InvalidInputError as exc:
        parser.error(str(exc))


def _leaves(group: BaseExceptionGroup[ToolCallError]) -> list[ToolCallError]:
    """The refusals of an exception group, nested task groups included."""
    out: list[ToolCallError] = []
    for exc in group.exceptions:
        out.extend(_leaves(exc) if isinstance(exc, BaseExceptionGroup) else [exc])
    return out


@dataclass
class CallRecord:
    """One recorded tool call (a line of the trace).

    Attributes:
        call: 1-based call number.
        tool: tool name.
        arguments: the arguments sent.
        is_error: whether the result was a tool error.
        texts: the text blocks of the result.
        images: the image files written (relative to the output folder).
        ms: wall time of the call in milliseconds.
    """

    call: int
    tool: str
    arguments: dict[str, Any]
    is_error: bool
    texts: list[str]
    images: list[str] = field(default_factory=list)
    ms: float = 0.0

    def as_json(self) -> dict[str, Any]:
        return {
            "call": self.call,
            "tool": self.tool,
            "arguments": self.arguments,
            "is_error": self.is_error,
            "texts": self.texts,
            "images": self.images,
            "ms": round(self.ms, 2),
        }

    def data(self) -> dict[str, Any]:
        """The first text block parsed as JSON (a tool's compact JSON status)."""
        if self.is_error:
            raise ToolCallError(f"{self.tool} failed: {' '.join(self.texts)}")
        return dict(json.loads(self.texts[0]))


class TracedClient:
    """Calls tools through an MCP client session and records each call.

    Args:
        client: an open `mcp.Client` (in memory, stdio or HTTP).
        out_dir: folder for `trace.jsonl` and `images/`; None keeps records in memory only.
    """

    def __init__(self, client: Any, out_dir: Path | None = None) -> None:
        self.client = client
        self.out_dir = out_dir
        self.records: list[CallRecord] = []
        self.resource_reads = 0
        self._trace = None
        if out_dir is not None:
            (out_dir / "images").mkdir(parents=True, exist_ok=True)
            self._trace = (out_dir / "trace.jsonl").open("w", encoding="utf-8")

    async def call(
        self, tool: str, arguments: dict[str, Any], keep_images: bool = True
    ) -> CallRecord:
        """Call `tool`; record and return the result (tool errors are recorded, not raised).

        Args:
            tool: the tool name.
            arguments: its arguments.
            keep_images: write the result's images to `images/` (else they are dropped).
        """
        start = time.perf_counter()
        result = await self.client.call_tool(tool, arguments)
        ms = (time.perf_counter() - start) * 1000.0
        index = len(self.records) + 1
        texts: list[str] = []
        images: list[str] = []
        for k, block in enumerate(result.content):
            if block.type == "text":
                texts.append(block.text)
            elif block.type == "image" and keep_images:
                ext = "jpg" if block.mime_type == "image/jpeg" else "png"
                name = f"images/{index:04d}_{tool}_{k}.{ext}"
                if self.out_dir is not None:
                    (self.out_dir / name).write_bytes(base64.b64decode(block.data))
                images.append(name)
        record = CallRecord(index, tool, arguments, bool(result.is_error), texts, images, ms)
        self.records.append(record)
        if self._trace is not None:
            self._trace.write(json.dumps(record.as_json()) + "\n")
            self._trace.flush()
        return record

    async def resource(self, uri: str) -> Any:
        """A JSON resource of the server (`glmap://current/regions`), parsed; resource reads
        are not tool calls and are counted apart (`resource_reads`), not traced."""
        result = await self.client.read_resource(uri)
        self.resource_reads += 1
        return json.loads(result.contents[0].text)

    def close(self) -> None:
        if self._trace is not None:
            self._trace.close()
            self._trace = None
