"""The in-process tools in the shapes of pydantic-ai, LangChain and smolagents.

Each adapter imports its framework when called, so glmap_tools needs none of them. What
the model reads is the same text the MCP server sends (`as_text`): compact `key: value`
lines, or the JSON and notes of an ImageResult. Images go where the framework takes them:

- pydantic-ai: a `Tool` over the async function; a GLMapError becomes `ModelRetry` with
  its message; images follow the text as `BinaryContent`.
- LangChain: a `StructuredTool` (`content_and_artifact`); a GLMapError becomes a
  `ToolException`, returned to the model as text; images stay in the artifact (the result).
- smolagents: a `Tool` subclass with output "string"; errors are raised with their
  message; images are dropped (its tools return one value).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol

from glmap_tools.app.results import as_text, pictures_of
from glmap_tools.errors import GLMapError

# Imports inside functions stay there: optional: langchain_core, pydantic_ai, smolagents.


class Toolset(Protocol):
    """What the adapters use of a `glmap_tools.toolset.Toolset`."""

    @property
    def names(self) -> list[str]: ...
    def call(self, name: str, arguments: Mapping[str, Any] | None = None) -> Any: ...
    async def acall(self, name: str, arguments: Mapping[str, Any] | None = None) -> Any: ...
    def dress(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]: ...
    def description(self, name: str) -> str: ...
    def input_schema(self, name: str) -> dict[str, Any]: ...
    def arg_text(self, name: str, arg: str) -> str: ...


# JSON schema types smolagents accepts for a tool input.
_SMOL_TYPES = {"string", "boolean", "integer", "number", "array", "object"}


def pydantic_ai_tools(toolset: Toolset) -> list[Any]:
    """pydantic-ai `Tool`s: the async functions, text (and images) back, errors as retries."""
    from pydantic_ai import BinaryContent, ModelRetry, Tool

    def make(name: str) -> Any:
        async def run(**kwargs: Any) -> Any:
            try:
                result = await toolset.acall(name, kwargs)
            except GLMapError as exc:
                raise ModelRetry(str(exc)) from exc
            pictures = pictures_of(result)
            if not pictures:
                return as_text(result)
            images = [BinaryContent(data=p.data, media_type=p.mime_type) for p in pictures]
            return [as_text(result), *images]

        fn = toolset.dress(name, run)
        return Tool(fn, takes_ctx=False, name=name, description=toolset.description(name))

    return [make(n) for n in toolset.names]


def langchain_tools(toolset: Toolset) -> list[Any]:
    """LangChain `StructuredTool`s: the tool's JSON schema as args_schema; the text goes to
    the model and the result object (with its images) is the ToolMessage artifact."""
    from langchain_core.tools import StructuredTool, ToolException

    def make(name: str) -> Any:
        def run(**kwargs: Any) -> tuple[str, Any]:
            try:
                result = toolset.call(name, kwargs)
            except GLMapError as exc:
                raise ToolException(str(exc)) from exc
            return as_text(result), result

        async def arun(**kwargs: Any) -> tuple[str, Any]:
            try:
                result = await toolset.acall(name, kwargs)
            except GLMapError as exc:
                raise ToolException(str(exc)) from exc
            return as_text(result), result

        return StructuredTool(
            name=name,
            description=toolset.description(name),
            args_schema=toolset.input_schema(name),
            func=run,
            coroutine=arun,
            response_format="content_and_artifact",
            handle_tool_error=True,
        )

    return [make(n) for n in toolset.names]


def smolagents_inputs(toolset: Toolset, name: str) -> dict[str, dict[str, Any]]:
    """A tool's arguments as smolagents `inputs`: type, description, nullable if optional."""
    schema = toolset.input_schema(name)
    required = set(schema.get("required", []))
    inputs = {}
    for arg, prop in schema.get("properties", {}).items():
        kind = prop.get("type")
        entry: dict[str, Any] = {
            "type": kind if kind in _SMOL_TYPES else "object",
            "description": toolset.arg_text(name, arg),
        }
        if arg not in required:
            entry["nullable"] = True
        inputs[arg] = entry
    return inputs


def smolagents_tools(toolset: Toolset) -> list[Any]:
    """smolagents `Tool`s returning the text a model reads (smolagents keeps no images)."""
    from smolagents import Tool

    def make(name: str) -> Any:
        class GLMapTool(Tool):  # type: ignore[misc]
            skip_forward_signature_validation = True

            def forward(self, **kwargs: Any) -> str:
                return as_text(toolset.call(name, kwargs))

        GLMapTool.name = name
        GLMapTool.description = toolset.description(name)
        GLMapTool.inputs = smolagents_inputs(toolset, name)
        GLMapTool.output_type = "string"
        GLMapTool.__name__ = GLMapTool.__qualname__ = f"{name}_tool"
        return GLMapTool()

    return [make(n) for n in toolset.names]
