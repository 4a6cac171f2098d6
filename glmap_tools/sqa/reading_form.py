"""The form a situation text is read into (`glmap_tools.sqa.reading`, or an LLM's reading):
where I am, what I face, and the objects at my sides or clock hours."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from glmap_tools.errors import InvalidInputError

Side = Literal["left", "right", "behind", "front"]
SIDES: tuple[str, ...] = ("left", "right", "behind", "front")
SIDE_BEARING = {"front": 0.0, "left": 90.0, "right": -90.0, "behind": 180.0}  # deg, + = left


@dataclass(frozen=True)
class Constraint:
    """An object at an egocentric side (left / right / behind / front) or clock hour.

    Attributes:
        object: its words ("lamp", "white door").
        side: left / right / behind / front, or None when `clock` is given.
        clock: 1..12 (12 straight ahead, 3 to the right), or None when `side` is given.
    """

    object: str
    side: Side | None = None
    clock: int | None = None

    def __post_init__(self) -> None:
        if (self.side is None) == (self.clock is None):
            raise InvalidInputError(
                f"constraint on {self.object!r}: give exactly one of side "
                f"({'/'.join(SIDES)}) and clock (1..12)."
            )
        if self.side is not None and self.side not in SIDES:
            raise InvalidInputError(f"side {self.side!r} is not one of {list(SIDES)}.")
        if self.clock is not None and not 1 <= self.clock <= 12:
            raise InvalidInputError(f"clock {self.clock!r} must be an hour 1..12.")

    @property
    def bearing_deg(self) -> float:
        """Where the object should lie, degrees from straight ahead (+ = left)."""
        if self.side is not None:
            return SIDE_BEARING[self.side]
        b = -30.0 * (self.clock or 12)
        return (b + 180.0) % 360.0 - 180.0 if b != -180.0 else 180.0


@dataclass(frozen=True)
class SituationReading:
    """Where a situation puts me: position, facing and egocentric constraints.

    Attributes:
        anchor: the object (or room) I am at, with its qualifying relations ("kitchen
            sink", "white cabinet next to the fridge"); '' when the text names none.
        relation: how I am placed to the anchor ("at", "on", "in front of", "between", ...).
        posture: standing / sitting / lying / ..., or None.
        activity: what I am doing ("rinsing a cup"), or None.
        near: other objects the position names ("between the sofa and the table": table).
        facing: the object I face, or None.
        constraints: objects at egocentric sides or clock hours.
    """

    anchor: str = ""
    relation: str = ""
    posture: str | None = None
    activity: str | None = None
    near: tuple[str, ...] = ()
    facing: str | None = None
    constraints: tuple[Constraint, ...] = field(default_factory=tuple)

    @property
    def clean(self) -> bool:
        """An anchor and something that fixes the heading (facing or a constraint)."""
        return bool(self.anchor) and (self.facing is not None or bool(self.constraints))

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form (the shape `from_dict` and `locate_situation` accept)."""
        return {
            "anchor": self.anchor,
            "relation": self.relation,
            "posture": self.posture,
            "activity": self.activity,
            "near": list(self.near),
            "facing": self.facing,
            "constraints": [
                {"object": c.object, "side": c.side, "clock": c.clock} for c in self.constraints
            ],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SituationReading:
        """The reading from `as_dict`'s shape (missing keys take their defaults)."""
        if not isinstance(data, dict):
            raise InvalidInputError(
                f"a situation reading is a JSON object, not {type(data).__name__}."
            )
        unknown = set(data) - {
            "anchor",
            "relation",
            "posture",
            "activity",
            "near",
            "facing",
            "constraints",
        }
        if unknown:
            raise InvalidInputError(f"unknown situation reading keys {sorted(unknown)}.")
        cons = tuple(
            Constraint(str(c["object"]), c.get("side"), c.get("clock"))
            for c in data.get("constraints") or []
        )
        return cls(
            anchor=str(data.get("anchor") or ""),
            relation=str(data.get("relation") or ""),
            posture=data.get("posture"),
            activity=data.get("activity"),
            near=tuple(str(n) for n in data.get("near") or ()),
            facing=(str(data["facing"]) if data.get("facing") else None),
            constraints=cons,
        )
