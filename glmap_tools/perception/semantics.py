"""`FrameSemantics`: what perception says about one frame (paper: S_t)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from glmap_tools.checks import is_integer
from glmap_tools.errors import InvalidInputError


@dataclass(frozen=True)
class ObjectObservation:
    """One instance seen in a frame (local id n~_o, description T_o, its mask).

    Attributes:
        local_id: id within this frame only.
        label: short category, e.g. "chair".
        description: open-vocabulary description; may be empty (the label is used then).
        mask: [H, W] bool pixels of the instance.
    """

    local_id: int
    label: str
    description: str
    mask: np.ndarray  # [H, W]

    @property
    def text(self) -> str:
        """The text that is embedded and stored: the description, else the label."""
        return self.description.strip() or self.label.strip()


@dataclass(frozen=True)
class GroupObservation:
    """One region seen in a frame (local id n~_r, description T_r, member local ids I~_r)."""

    local_id: int
    description: str
    members: tuple[int, ...]


@dataclass(frozen=True)
class FrameSemantics:
    """The instances and regions perceived in one frame."""

    objects: list[ObjectObservation] = field(default_factory=list)
    groups: list[GroupObservation] = field(default_factory=list)

    def validate(self, height: int, width: int) -> None:
        """Raise InvalidInputError on duplicate ids, bad masks or unknown group members."""
        if not isinstance(self.objects, list | tuple) or not isinstance(self.groups, list | tuple):
            raise InvalidInputError(
                "FrameSemantics.objects and .groups must be lists of ObjectObservation and "
                "GroupObservation."
            )
        seen: set[int] = set()
        for obj in self.objects:
            _check_object_fields(obj)
            if obj.local_id in seen:
                raise InvalidInputError(
                    f"object local id {obj.local_id} appears twice; give each object in a "
                    "frame its own id."
                )
            seen.add(obj.local_id)
            if not obj.text:
                raise InvalidInputError(
                    f"object {obj.local_id} has neither a label nor a description; give it one."
                )
            for name, value in (("label", obj.label), ("description", obj.description)):
                _check_unicode(value, f"object {obj.local_id}'s {name}")
            if obj.mask.shape != (height, width):
                raise InvalidInputError(
                    f"mask of object {obj.local_id} has shape {obj.mask.shape} but the frame is "
                    f"{(height, width)}; masks must match the depth image pixel for pixel."
                )
            if not obj.mask.any():
                raise InvalidInputError(
                    f"mask of object {obj.local_id} ({obj.text!r}) is empty; drop the object "
                    "or give it the pixels it covers."
                )
        group_ids: set[int] = set()
        for group in self.groups:
            _check_group_fields(group)
            if group.local_id in group_ids:
                raise InvalidInputError(
                    f"group local id {group.local_id} appears twice; give each group its own id."
                )
            group_ids.add(group.local_id)
            if not group.description.strip():
                raise InvalidInputError(f"group {group.local_id} has no description; add one.")
            _check_unicode(group.description, f"group {group.local_id}'s description")
            unknown = sorted(set(group.members) - seen)
            if unknown:
                raise InvalidInputError(
                    f"group {group.local_id} ({group.description!r}) lists unknown member ids "
                    f"{unknown}; members must be object ids of this frame {sorted(seen)}."
                )


def _check_object_fields(obj: object) -> None:
    """Refuse an object observation whose fields are not of their kinds (a library caller's
    slip): an integer local id, text label and description, a boolean mask of two axes."""
    if not isinstance(obj, ObjectObservation):
        raise InvalidInputError(f"objects holds {obj!r:.60}, not an ObjectObservation.")
    what = f"object {obj.local_id!r:.40}"
    if not is_integer(obj.local_id):
        raise InvalidInputError(f"{what}: its local_id is not an integer; number the objects.")
    if not isinstance(obj.label, str) or not isinstance(obj.description, str):
        raise InvalidInputError(f"{what}: its label and description must be text (str).")
    mask = obj.mask
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.ndim != 2:
        shown = f"{mask.dtype} [{mask.shape}]" if isinstance(mask, np.ndarray) else type(mask)
        raise InvalidInputError(
            f"{what}: its mask is {shown}; give a boolean [H, W] array (e.g. labels == id)."
        )


def _check_group_fields(group: object) -> None:
    """Refuse a group observation whose fields are not of their kinds."""
    if not isinstance(group, GroupObservation):
        raise InvalidInputError(f"groups holds {group!r:.60}, not a GroupObservation.")
    what = f"group {group.local_id!r:.40}"
    if not is_integer(group.local_id):
        raise InvalidInputError(f"{what}: its local_id is not an integer; number the groups.")
    if not isinstance(group.description, str):
        raise InvalidInputError(f"{what}: its description must be text (str).")
    members = group.members
    if not isinstance(members, list | tuple) or not all(is_integer(m) for m in members):
        raise InvalidInputError(
            f"{what}: its members {members!r:.60} must be a list of object local ids."
        )


def _check_unicode(text: str, what: str) -> None:
    """Refuse text that cannot be stored: a lone surrogate has no UTF-8 encoding."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise InvalidInputError(
            f"{what} {text[:40]!r} holds a lone surrogate at character {exc.start}, which is "
            "not text; decode the source with errors='replace' (or drop it) first."
        ) from None
