"""`Toolset`: the GLMap tools in this process, for agent frameworks without MCP.

The functions are the ones the MCP server registers (glmap_tools.app.catalog), called
with a `Call` on this toolset's app state: the same names, descriptions, parameters,
validation and results. A call's arguments are tidied and validated as the server does
it (glmap_tools.app.arguments; nulls = omitted, `topK` = `top_k`, "5" = 5; anything else a clear
InvalidInputError naming the argument); results are the pydantic models the server sends as
structured content, or an `ImageResult` (text blocks and `Picture`s) for tools with images.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Awaitable, Callable, Iterable, Mapping
from contextlib import ExitStack
from typing import TYPE_CHECKING, Any

import anyio.to_thread
from anyio.from_thread import start_blocking_portal
from pydantic import ValidationError

from glmap_tools.app.arguments import (
    input_schema,
    parameters,
    tidy_arguments,
    validate_arguments,
    validation_message,
)
from glmap_tools.app.background import Background
from glmap_tools.app.catalog import TOOLS
from glmap_tools.app.config import ServerConfig
from glmap_tools.app.lifespan import needed_tasks, opened_state
from glmap_tools.app.listing import lean_listing
from glmap_tools.app.results import compact_description, compact_schema
from glmap_tools.app.runtime import (
    CALL_PARAMETER,
    AppState,
    Call,
    PerceptionBackend,
    ProgressCallback,
    ToolSpec,
)
from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.toolset.flat import SEP, flat_schema, unflatten

if TYPE_CHECKING:
    from anyio.from_thread import BlockingPortal
    from mcp.types import Tool

    from glmap_tools.language.sampling import Sampler

# Imports inside functions stay there: mcp load on first use: the tools load before these do, in the
# server and the in-process toolset alike; circle: toolset.adapters import this module.


class Toolset:
    """The GLMap tools over one app state (embedder, sessions, maps) in this process.

    Use it as a context manager (or call `open()` / `close()`); the embedder loads once.
    `call(name, arguments)` runs a tool; `functions()` gives plain functions with the tools'
    names, docstrings (description, then Google-style Args) and signatures, for
    `ollama.chat(tools=...)` and the like; `as_pydantic_ai_tools()`,
    `as_langchain_tools()` and `as_smolagents_tools()` adapt them to those frameworks.

    Args:
        config: server settings (maps folder, embedder, limits); default `ServerConfig()`.
        perception: turns a frame into semantics when observe_frame gets no annotations.
        tools: names of the tools to offer; default all.
        on_progress: called with (progress, total, message) as long calls advance.
        sampler: the model of `--llm sampling` parts (`config.llm`): an async function
            like `glmap_tools.language.sampling.Sampler`; None: those parts fall back.
    """

    def __init__(
        self,
        config: ServerConfig | None = None,
        perception: PerceptionBackend | None = None,
        *,
        tools: Iterable[str] | None = None,
        on_progress: ProgressCallback | None = None,
        sampler: Sampler | None = None,
    ) -> None:
        self.config = config or ServerConfig()
        self.perception = perception
        self.on_progress = on_progress
        self.sampler = sampler
        by_name = {t.name: t for t in TOOLS}
        names = list(by_name) if tools is None else list(tools)
        for name in names:
            if name not in by_name:
                raise UnknownIdError(f"no tool {name!r}; the tools are {', '.join(by_name)}.")
        self.specs = [by_name[n] for n in names]
        self._schemas = {s.name: input_schema(s.fn) for s in self.specs}
        self._background = Background()
        self._stack: ExitStack | None = None
        self._state: AppState | None = None
        self._portal: BlockingPortal | None = None

    # ------------------------------------------------------------------ lifetime

    def open(self) -> Toolset:
        """Build the app state (loads the embedder); idempotent."""
        if self._stack is None:
            stack = ExitStack()
            self._state = stack.enter_context(
                opened_state(self.config, self.perception, self._background)
            )
            self._stack = stack
        return self

    def close(self) -> None:
        """Close every session and stop the worker loop of the sync functions."""
        stack, self._stack, self._state, self._portal = self._stack, None, None, None
        if stack is not None:
            stack.close()

    def __enter__(self) -> Toolset:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def state(self) -> AppState:
        """The app state (opened on first use)."""
        self.open()
        assert self._state is not None
        return self._state

    # ------------------------------------------------------------------ calls

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.specs]

    def _spec(self, name: str) -> ToolSpec:
        for spec in self.specs:
            if spec.name == name:
                return spec
        raise UnknownIdError(f"no tool {name!r}; the tools are {', '.join(self.names)}.")

    async def acall(self, name: str, arguments: Mapping[str, Any] | None = None) -> Any:
        """Run tool `name` with `arguments` (validated as the MCP server validates them).

        Returns:
            The tool's result: a pydantic model, or an ImageResult for tools with images.

        Raises:
            GLMapError: what the MCP face reports as a tool error (bad arguments included).
        """
        spec = self._spec(name)
        given = dict(arguments or {})
        if any(SEP in key for key in given):  # flattened by `ollama_tools`' schemas
            given = unflatten(given)
        args = tidy_arguments(name, given, [p.name for p in parameters(spec.fn)])
        try:
            validated = validate_arguments(spec.fn, args)
        except ValidationError as exc:
            raise InvalidInputError(validation_message(name, exc)) from None
        state = self.state
        pending = self._background.pending(needed_tasks(name))
        if pending:
            names = [t.name for t in pending]
            await anyio.to_thread.run_sync(lambda: self._background.wait(names))
        call = Call(state, progress=self._progress, sampler=self.sampler)
        return await spec.fn(**validated, call=call)

    async def _progress(self, progress: float, total: float | None, message: str | None) -> None:
        if self.on_progress is not None:
            self.on_progress(progress, total, message)

    def call(self, name: str, arguments: Mapping[str, Any] | None = None) -> Any:
        """`acall` from synchronous code (runs on the toolset's own event loop thread)."""
        return self._blocking_portal().call(functools.partial(self.acall, name, arguments))

    def _blocking_portal(self) -> BlockingPortal:
        if self._portal is None:
            self.open()
            assert self._stack is not None
            self._portal = self._stack.enter_context(start_blocking_portal())
        return self._portal

    # ------------------------------------------------------------------ descriptions

    def tool_list(self) -> list[Tool]:
        """The tools as the MCP server lists them (tools/list), for these tools."""
        from mcp.types import Tool, ToolAnnotations

        lean = lean_listing([(s.name, s.fn.__doc__, self._schemas[s.name]) for s in self.specs])
        return [
            Tool(
                name=spec.name,
                description=description,
                input_schema=schema,
                annotations=ToolAnnotations.model_validate(spec.annotations.said()),
            )
            for spec, (description, schema) in zip(self.specs, lean, strict=True)
        ]

    def description(self, name: str) -> str:
        """The tool's description, as in tools/list."""
        return compact_description(self._spec(name).fn.__doc__ or "")

    def input_schema(self, name: str) -> dict[str, Any]:
        """The tool's input JSON schema, complete on its own (every argument described)."""
        return dict(compact_schema(self._schemas[name]))

    def openai_tools(self) -> list[dict[str, Any]]:
        """The tools in the OpenAI function-tool format (for `ollama.chat`, use
        `ollama_tools`: ollama drops what its own schema model does not know)."""
        return [
            {
                "type": "function",
                "function": {
                    "name": n,
                    "description": self.description(n),
                    "parameters": self.input_schema(n),
                },
            }
            for n in self.names
        ]

    def ollama_tools(self) -> list[dict[str, Any]]:
        """The tools for `ollama.chat(tools=...)`, whose `Tool` model keeps only the type,
        description, enum and items of each argument: object arguments are flattened
        (`pose__matrix`; `call` nests them back) and bounds and defaults are written into
        the descriptions (glmap_tools.toolset.flat)."""
        return [
            {
                "type": "function",
                "function": {
                    "name": n,
                    "description": self.description(n),
                    "parameters": flat_schema(self._schemas[n]),
                },
            }
            for n in self.names
        ]

    def docstring(self, name: str) -> str:
        """The description, then a Google-style Args section (what ollama, smolagents and
        pydantic-ai read): each argument's description, and its default when it has one."""
        args = list(self.input_schema(name).get("properties", {}))
        lines = [self.description(name)]
        if args:
            lines += ["", "Args:", *(f"    {a}: {self.arg_text(name, a)}" for a in args)]
        return "\n".join(lines)

    def arg_text(self, name: str, arg: str) -> str:
        """What argument `arg` of tool `name` is, in a few words, with its default."""
        prop = self.input_schema(name)["properties"][arg]
        return _arg_text(prop, self._schemas[name])

    def signature(self, name: str) -> inspect.Signature:
        """The tool function's signature without its `call` parameter."""
        sig = inspect.signature(self._spec(name).fn)
        kept = [p for p in sig.parameters.values() if p.name != CALL_PARAMETER]
        return sig.replace(parameters=kept)

    # ------------------------------------------------------------------ functions

    def dress(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """Give `fn` the tool's name, docstring, signature and annotations (without call)."""
        sig = self.signature(name)
        hints = {
            k: v
            for k, v in inspect.get_annotations(self._spec(name).fn).items()
            if k != CALL_PARAMETER
        }
        fn.__name__ = fn.__qualname__ = name
        fn.__doc__ = self.docstring(name)
        fn.__signature__ = sig  # type: ignore[attr-defined]
        fn.__annotations__ = hints
        fn.__module__ = self._spec(name).fn.__module__
        return fn

    def functions(self) -> list[Callable[..., Any]]:
        """A plain synchronous function per tool: name, docstring and signature of the tool
        (without `call`); it returns what `Toolset.call` returns."""

        def make(name: str) -> Callable[..., Any]:
            sig = self.signature(name)

            def run(*args: Any, **kwargs: Any) -> Any:
                return self.call(name, _bind(sig, args, kwargs))

            return self.dress(name, run)

        return [make(n) for n in self.names]

    def async_functions(self) -> list[Callable[..., Awaitable[Any]]]:
        """As `functions`, but coroutine functions (for async frameworks)."""

        def make(name: str) -> Callable[..., Awaitable[Any]]:
            sig = self.signature(name)

            async def run(*args: Any, **kwargs: Any) -> Any:
                return await self.acall(name, _bind(sig, args, kwargs))

            return self.dress(name, run)

        return [make(n) for n in self.names]

    # ------------------------------------------------------------------ frameworks

    def as_pydantic_ai_tools(self) -> list[Any]:
        """pydantic-ai `Tool`s (needs `pydantic-ai`); see glmap_tools.toolset.adapters."""
        from glmap_tools.toolset.adapters import pydantic_ai_tools

        return pydantic_ai_tools(self)

    def as_langchain_tools(self) -> list[Any]:
        """LangChain `StructuredTool`s (needs `langchain-core`)."""
        from glmap_tools.toolset.adapters import langchain_tools

        return langchain_tools(self)

    def as_smolagents_tools(self) -> list[Any]:
        """smolagents `Tool`s (needs `smolagents`)."""
        from glmap_tools.toolset.adapters import smolagents_tools

        return smolagents_tools(self)


def _bind(sig: inspect.Signature, args: tuple[Any, ...], kwargs: dict[str, Any]) -> dict[str, Any]:
    """Positional and keyword arguments as one mapping; unknown names pass through so the
    call reports them (with a suggestion) instead of a bare TypeError."""
    names = list(sig.parameters)
    if len(args) > len(names):
        raise InvalidInputError(f"too many positional arguments: the tool takes {names}.")
    return {**dict(zip(names, args, strict=False)), **kwargs}


def _arg_text(prop: Mapping[str, Any], raw: Mapping[str, Any]) -> str:
    """One argument's line in the Args section."""
    text = prop.get("description")
    ref = prop.get("$ref") or (prop.get("items") or {}).get("$ref")
    if text is None and isinstance(ref, str):
        model = raw.get("$defs", {}).get(ref.rsplit("/", 1)[-1], {})
        text = model.get("description")
    if text is None:
        kind = prop.get("type") or "object"
        text = f"one of {prop['enum']}" if "enum" in prop else str(kind)
    text = " ".join(str(text).split())
    default = prop.get("default")
    if default not in (None, "", []):  # compact_schema leaves out "" and false defaults
        text += f" (default {default!r})"
    return text
