"""The tool list a model reads: compact descriptions and input schemas, nothing said twice.

Each description has its line breaks folded and each input schema is compacted
(`results.compact_schema`); a model (`$defs`) shared by several tools, and an argument
described the same way in several (session, query, name), are described in the first only.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from glmap_tools.app.results import compact_description, compact_schema, strip_descriptions


def lean_listing(
    tools: Sequence[tuple[str, str | None, dict[str, Any]]],
) -> list[tuple[str, dict[str, Any]]]:
    """(description, input schema) of each tool as listed, from (name, description, schema)."""
    seen: dict[str, str] = {}  # $defs name -> the first tool that describes it
    said: set[tuple[str, str]] = set()  # (argument, description) already given
    out = []
    for name, description, raw in tools:
        schema = compact_schema(raw)
        for arg, prop in schema.get("properties", {}).items():
            text = prop.get("description")
            if text is not None and (arg, text) in said:
                del prop["description"]  # described in an earlier tool
            elif text is not None:
                said.add((arg, text))
        for model_name, model in schema.get("$defs", {}).items():
            if model_name in seen:
                schema["$defs"][model_name] = {
                    **strip_descriptions(model),
                    "description": f"as in {seen[model_name]}",
                }
            else:
                seen[model_name] = name
        out.append((compact_description(description or ""), schema))
    return out
