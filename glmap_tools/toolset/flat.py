"""Tool schemas for frameworks that keep only a few JSON-schema keywords per argument.

`ollama.chat(tools=...)` re-serialises every schema through its own `Tool` model, which
keeps `type`, `description`, `enum` and `items` of each argument and drops the rest:
defaults, bounds, and the `$ref` of an object argument (observe_frame's `rgb`, `depth`,
`pose`, `annotations`). `flat_schema` gives a schema that survives it:

- object arguments are flattened: `pose: {matrix, camera}` becomes `pose__matrix` and
  `pose__camera` (`SEP`), nested as deep as the schema goes; `unflatten` turns a call's
  arguments back into the nested form the tool validates;
- bounds, lengths and defaults are written into the description ("integer 1..200,
  default 1");
- array items are given whole, with every `$ref` resolved in place.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

SEP = "__"
KEEP = ("type", "description", "enum", "items")


def _resolve(prop: Mapping[str, Any], defs: Mapping[str, Any]) -> dict[str, Any]:
    """`prop` with its `$ref` and a nullable `anyOf` replaced by what they point to."""
    out = dict(prop)
    options = out.pop("anyOf", None)
    if options:
        kept = [o for o in options if o.get("type") != "null"]
        if len(kept) == 1:
            out = {**_resolve(kept[0], defs), **out}
        else:
            out["anyOf"] = options
    ref = out.pop("$ref", None)
    if isinstance(ref, str):
        target = _resolve(defs.get(ref.rsplit("/", 1)[-1], {}), defs)
        out = {**target, **out}
    return out


def _inline(prop: Mapping[str, Any], defs: Mapping[str, Any]) -> dict[str, Any]:
    """A schema with every `$ref` inside it resolved in place (for array items)."""
    out = _resolve(prop, defs)
    if isinstance(out.get("properties"), Mapping):
        out["properties"] = {k: _inline(v, defs) for k, v in out["properties"].items()}
    if isinstance(out.get("items"), Mapping):
        out["items"] = _inline(out["items"], defs)
    out.pop("title", None)
    return out


def _constraints(prop: Mapping[str, Any]) -> str:
    """What the dropped keywords said, in words: 'integer 1..200, default 1'."""
    parts = []
    lo, hi = prop.get("minimum", prop.get("exclusiveMinimum")), prop.get("maximum")
    if lo is not None or hi is not None:
        parts.append(f"{'' if lo is None else lo}..{'' if hi is None else hi}")
    if "maxLength" in prop:
        parts.append(f"at most {prop['maxLength']} characters")
    if "maxItems" in prop:
        parts.append(f"at most {prop['maxItems']} items")
    if "default" in prop and prop["default"] not in (None, ""):
        parts.append(f"default {prop['default']!r}")
    return ", ".join(parts)


def _leaf(prop: Mapping[str, Any], defs: Mapping[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in prop.items() if k in KEEP}
    if "items" in out:
        out["items"] = _inline(out["items"], defs)
    if "type" not in out and "anyOf" in prop:
        out["type"] = [o.get("type") for o in prop["anyOf"] if o.get("type")]
    said = _constraints(prop)
    if said:
        out["description"] = f"{out.get('description', '').rstrip('.')} ({said})".lstrip()
    return out


def flat_schema(schema: Mapping[str, Any]) -> dict[str, Any]:
    """The input `schema` of a tool with object arguments flattened (module docstring)."""
    defs = schema.get("$defs", {})
    properties: dict[str, Any] = {}
    required: list[str] = []

    def add(name: str, prop: Mapping[str, Any], needed: bool, context: str = "") -> None:
        full = _resolve(prop, defs)
        inner = full.get("properties")
        if full.get("type") == "object" and isinstance(inner, Mapping) and inner:
            wanted = set(full.get("required", ()))
            what = f"{context}{name}: {full['description']}; " if full.get("description") else ""
            for key, sub in inner.items():
                add(f"{name}{SEP}{key}", sub, needed and key in wanted, what)
            return
        leaf = _leaf(full, defs)
        if context:
            leaf["description"] = f"{context}{leaf.get('description', '')}".rstrip("; ")
        properties[name] = leaf
        if needed:
            required.append(name)

    wanted = set(schema.get("required", ()))
    for name, prop in schema.get("properties", {}).items():
        add(name, prop, name in wanted)
    out: dict[str, Any] = {"type": "object", "properties": properties}
    if required:
        out["required"] = required
    return out


def unflatten(arguments: Mapping[str, Any]) -> dict[str, Any]:
    """Arguments named `a__b__c` nested back as {'a': {'b': {'c': ...}}}; others as given."""
    out: dict[str, Any] = {}
    for key, value in arguments.items():
        parts = key.split(SEP) if SEP in key.strip("_") else [key]
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                return dict(arguments)  # a name clash: leave the call as it came
        node[parts[-1]] = value
    return out
