"""The annotated perception backend: masks and labels given with the frame.

Annotation format (per frame), shared by the simulator, `glmap build` and the MCP server:

- an instance-id mask: [H, W] integer image (PNG uint8/uint16), 0 = no object;
- a JSON object::

    {"objects": [{"id": 3, "label": "chair", "description": "a blue metal chair"}],
     "groups":  [{"id": 1, "description": "dining area: a table and chairs", "members": [3]}]}

  `id` values of objects are the mask values; `members` are object ids of the same frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS
from glmap_tools.perception.semantics import FrameSemantics, GroupObservation, ObjectObservation


def _int_field(entry: Mapping[str, Any], key: str, where: str) -> int:
    value = entry.get(key)
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidInputError(f"{where} needs an integer {key!r}, got {value!r}.")
    return int(value)


def _text_field(entry: Mapping[str, Any], where: str) -> str:
    """The entry's description, at most MAX_DESCRIPTION_CHARS characters."""
    text = str(entry.get("description", "") or "")
    if len(text) > MAX_DESCRIPTION_CHARS:
        raise InvalidInputError(
            f"{where} has a description of {len(text)} characters; the limit is "
            f"{MAX_DESCRIPTION_CHARS}: shorten it (a sentence or two per object)."
        )
    return text


def semantics_from_annotation(
    instance_mask: np.ndarray, annotation: Mapping[str, Any]
) -> FrameSemantics:
    """Build `FrameSemantics` from an instance-id mask and its label JSON (already parsed).

    Args:
        instance_mask: [H, W] integer ids, 0 = background.
        annotation: {"objects": [...], "groups": [...]} as documented in this module.

    Raises:
        InvalidInputError: malformed entries, an object with no pixels, unknown group members.
    """
    mask = np.asarray(instance_mask)
    if mask.ndim != 2 or not np.issubdtype(mask.dtype, np.integer):
        raise InvalidInputError(
            f"instance mask has shape {mask.shape} and dtype {mask.dtype}; pass an [H, W] "
            "integer image whose values are object ids (0 = none)."
        )
    if not isinstance(annotation, Mapping):
        raise InvalidInputError(
            f"annotation must be a JSON object with 'objects' and 'groups', got "
            f"{type(annotation).__name__}."
        )
    unknown_keys = set(annotation) - {"objects", "groups"}
    if unknown_keys:
        raise InvalidInputError(
            f"annotation has unknown keys {sorted(unknown_keys)}; use 'objects' and 'groups'."
        )
    objects = []
    for i, entry in enumerate(annotation.get("objects", [])):
        where = f"annotation objects[{i}]"
        if not isinstance(entry, Mapping):
            raise InvalidInputError(f"{where} must be an object, got {entry!r}.")
        obj_id = _int_field(entry, "id", where)
        if obj_id <= 0:
            raise InvalidInputError(f"{where} has id {obj_id}; object ids are > 0 (0 = none).")
        label = str(entry.get("label", "") or "")
        description = _text_field(entry, where)
        objects.append(ObjectObservation(obj_id, label, description, mask == obj_id))
    groups = []
    for i, entry in enumerate(annotation.get("groups", [])):
        where = f"annotation groups[{i}]"
        if not isinstance(entry, Mapping):
            raise InvalidInputError(f"{where} must be an object, got {entry!r}.")
        members = entry.get("members", [])
        if not isinstance(members, list | tuple) or not all(
            isinstance(m, int | np.integer) and not isinstance(m, bool) for m in members
        ):
            raise InvalidInputError(f"{where} 'members' must be a list of object ids.")
        groups.append(
            GroupObservation(
                _int_field(entry, "id", where),
                _text_field(entry, where),
                tuple(int(m) for m in members),
            )
        )
    semantics = FrameSemantics(objects, groups)
    semantics.validate(*mask.shape)
    return semantics
