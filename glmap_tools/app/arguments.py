"""A tool's arguments: the pydantic model built from its function's signature, the argument
types several tools share, names tidied, validation errors as one line.

Every parameter but `call` is a field, with its annotation (`Annotated[..., Field(...)]`)
and default, in signature order: the model the MCP SDK builds for the same function, so
its JSON schema is the tool's input schema in tools/list and both faces validate alike
(a test holds the two schemas equal).
"""

from __future__ import annotations

import difflib
import functools
import inspect
import json
import unicodedata
from collections.abc import Callable, Mapping, Sequence
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, create_model

from glmap_tools.app.runtime import CALL_PARAMETER
from glmap_tools.errors import InvalidInputError

# ---------------------------------------------------------------------- shared types

MAX_HANDLE = 64


def _handle(value: str) -> str:
    if len(value) > MAX_HANDLE:
        raise ValueError(
            f"a session handle has at most {MAX_HANDLE} characters; pass the one new_map returned"
        )
    return value


# Characters that make stored words render differently from what they are (issue 41):
# refused, naming the code point. Bidirectional controls reorder what follows them
# ("rosu\u202eriahc" shows as "rosuchair"), line and paragraph separators break a label
# over lines without a newline, tag characters spell text no one sees but a model reads.
BIDI_CONTROLS = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e")
BIDI_CONTROLS |= frozenset("\u2066\u2067\u2068\u2069")
SEPARATORS = frozenset("\u2028\u2029")
TAGS = range(0xE0000, 0xE0080)
# Invisible characters with no part in a word (copy-and-paste leftovers): removed. The
# zero-width (non-)joiners stay: Persian, Indic scripts and emoji sequences need them.
INVISIBLE = {ord(c): None for c in "\u200b\u2060\ufeff\u00ad"}


def _code_point(c: str) -> str:
    return f"U+{ord(c):04X} {unicodedata.name(c, 'unnamed')}"


def _stored_text(allowed: str) -> Any:
    """A validator for words stored in the map (labels, descriptions).

    Refuses control characters (NUL, ESC, ...) other than `allowed`, bidirectional
    controls, line and paragraph separators and tag characters, each named with its code
    point; removes zero-width spaces, word joiners, byte-order marks and soft hyphens.
    """

    def check(value: str) -> str:
        bad = sorted({c for c in value if unicodedata.category(c) == "Cc" and c not in allowed})
        if bad:
            shown = ", ".join(repr(c) for c in bad[:5])
            raise ValueError(
                f"contains control characters ({shown}); send plain text (they would be "
                "stored and shown to every client: terminal escapes, NUL)"
            )
        odd = sorted({c for c in value if c in BIDI_CONTROLS or c in SEPARATORS})
        odd += sorted({c for c in value if ord(c) in TAGS})
        if odd:
            shown = ", ".join(_code_point(c) for c in odd[:3])
            fix = "use a newline for a line break" if "\n" in allowed else "a label is one line"
            raise ValueError(
                f"contains {shown}; remove it ({fix}). "
                "Bidirectional controls, line separators and tag characters make stored "
                "words read differently from what they are, to people and to models"
            )
        return value.translate(INVISIBLE)

    return AfterValidator(check)


# Words that are stored in the map (labels, descriptions): printable text only (issues 27, 41).
Label = Annotated[str, _stored_text("")]
Description = Annotated[str, _stored_text("\t\n\r")]


SessionArg = Annotated[
    str,
    AfterValidator(_handle),
    Field(description="a handle from new_map (shared HTTP servers)"),
]


# ---------------------------------------------------------------------- models


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


# ---------------------------------------------------------------------- arguments


def _key(name: str) -> str:
    return name.replace("-", "").replace("_", "").lower()


def tidy_arguments(tool: str, arguments: Mapping[str, Any], names: Sequence[str]) -> dict[str, Any]:
    """The arguments of a call as frameworks send them, made unambiguous.

    A null is an omitted argument (its default applies; a required one is reported
    missing). A name that differs from a parameter only in case, '-' or '_' (topK, top-k)
    is that parameter. Any other unknown name is refused. Strings for numbers are left to
    validation, which accepts the unambiguous ones ("5" for an integer).

    Raises:
        InvalidInputError: an unknown argument, or two names for one parameter.
    """
    by_key = {_key(n): n for n in names}
    out: dict[str, Any] = {}
    for raw, value in arguments.items():
        name = raw if raw in names else by_key.get(_key(raw))
        if name is None:
            close = difflib.get_close_matches(raw, list(names), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InvalidInputError(
                f"{tool} has no argument {raw!r}{hint}; its arguments are {', '.join(names)}."
            )
        if name in out:
            raise InvalidInputError(f"{tool}: {name!r} is given twice (as {raw!r}); give it once.")
        if value is not None:
            out[name] = value
    return out


def validation_message(tool: str, exc: ValidationError) -> str:
    """A pydantic validation error as one line per bad argument: where, what, the value."""
    lines = []
    for err in exc.errors(include_url=False):
        where = ".".join(str(p) for p in err["loc"]) or "arguments"
        got = err.get("input")
        shown = repr(got) if isinstance(got, str | int | float | bool) else type(got).__name__
        if err["type"] == "missing":
            lines.append(f"{where}: required, but not given")
        else:
            lines.append(f"{where}: {err['msg']} (got {shown[:80]})")
    return f"{tool}: invalid arguments; " + "; ".join(lines)
