"""A tool's arguments as a pydantic model built from its function's signature.

Every parameter but `call` is a field, with its annotation (`Annotated[..., Field(...)]`)
and default, in signature order: the model the MCP SDK builds for the same function, so
its JSON schema is the tool's input schema in tools/list and both faces validate alike
(a test holds the two schemas equal).
"""

from __future__ import annotations

import functools
import inspect
import json
from collections.abc import Callable, Mapping
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, create_model

from glmap_tools.app.runtime import CALL_PARAMETER


class Arguments(BaseModel):
    """The base of every tool's argument model."""

    model_config = ConfigDict(arbitrary_types_allowed=True)


def parameters(fn: Callable[..., Any]) -> list[inspect.Parameter]:
    """The tool function's parameters less `call`, in order (annotations evaluated)."""
    signature = inspect.signature(fn, eval_str=True)
    return [p for p in signature.parameters.values() if p.name != CALL_PARAMETER]


@functools.cache
def argument_model(fn: Callable[..., Any]) -> type[Arguments]:
    """The pydantic model of tool function `fn`'s arguments (`<name>Arguments`)."""
    fields: dict[str, Any] = {}
    for p in parameters(fn):
        annotation = p.annotation if p.annotation is not inspect.Parameter.empty else Any
        if hasattr(BaseModel, p.name):
            raise TypeError(f"tool {fn.__name__}: parameter {p.name!r} shadows a BaseModel name")
        typed: Any = Annotated[(annotation, Field())]
        fields[p.name] = typed if p.default is inspect.Parameter.empty else (typed, p.default)
    model: type[Arguments] = create_model(f"{fn.__name__}Arguments", __base__=Arguments, **fields)
    return model


def input_schema(fn: Callable[..., Any]) -> dict[str, Any]:
    """The JSON schema of `fn`'s arguments, before compacting (`results.compact_schema`)."""
    return argument_model(fn).model_json_schema(by_alias=True)


def validate_arguments(fn: Callable[..., Any], arguments: Mapping[str, Any]) -> dict[str, Any]:
    """`arguments` validated into keyword arguments of `fn` (models stay models).

    A string given for an argument that is not a string and parses as a JSON list or
    object is parsed first (clients send nested arguments as JSON text).

    Raises:
        pydantic.ValidationError: an argument is missing, unknown or out of bounds.
    """
    model = argument_model(fn)
    given = dict(arguments)
    for key, value in arguments.items():
        info = model.model_fields.get(key)
        if info is None or not isinstance(value, str) or info.annotation is str:
            continue
        try:
            parsed = json.loads(value)
        except (ValueError, RecursionError):
            continue
        if not isinstance(parsed, str | int | float):
            given[key] = parsed
    validated = model.model_validate(given)
    return {name: getattr(validated, name) for name in type(validated).model_fields}
