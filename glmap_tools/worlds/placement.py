"""Placement rules for furnishing a rectangular room: against walls, facing, around, on top.

Every rule returns a `Placed` object or None when nothing fits (the caller decides whether the
object was optional). Floor objects never overlap each other, the walls or the clearance
zone in front of a door; flat objects (rugs) and objects on top of others are exempt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from glmap_tools.sim.architecture import WALL_THICKNESS
from glmap_tools.sim.layout import Opening, Room, rects_overlap, yaw_matrix

DOOR_CLEARANCE = 0.9  # metres kept free in front of a door, on both sides
WALL_GAP = 0.02  # metres between a wall and the back of furniture against it
WALKWAY = 0.8  # metres: width kept free between the doors of a room one walks through
SIDES = ("south", "east", "north", "west")


def _segment_zone(p: np.ndarray, q: np.ndarray, half_across: np.ndarray) -> np.ndarray:
    """The rectangle [4, 2] from p to q, `half_across` to either side."""
    return np.stack([p - half_across, q - half_across, q + half_across, p + half_across])


@dataclass
class ObjectSpec:
    """What to place: category, mesh, real size (w, d, h) and attributes."""

    category: str
    mesh: str
    size: tuple[float, float, float]
    attributes: dict[str, str] = field(default_factory=dict)
    flat: bool = False  # rugs: may overlap floor objects


@dataclass
class Placed:
    """A placed object (before ids are assigned)."""

    spec: ObjectSpec
    position: np.ndarray  # [3] base centre
    heading: float
    room: int
    support: Placed | None = None
    side: str = ""
    key: int = 0  # placement order, filled by the planner

    @property
    def size(self) -> np.ndarray:  # [3]
        return np.asarray(self.spec.size, dtype=np.float64)

    @property
    def top(self) -> float:
        return float(self.position[2] + self.spec.size[2])

    @property
    def front(self) -> np.ndarray:  # [2]
        return np.array([math.cos(self.heading), math.sin(self.heading)])

    def footprint(self, margin: float = 0.0) -> np.ndarray:  # [4, 2]
        w, d = self.spec.size[0] / 2 + margin, self.spec.size[1] / 2 + margin
        local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]])
        return local @ yaw_matrix(self.heading + math.pi / 2)[:2, :2].T + self.position[:2]


def side_heading(side: str) -> float:
    """Heading of an object standing against `side`'s wall, facing into the room."""
    return {"south": math.pi / 2, "north": -math.pi / 2, "west": 0.0, "east": math.pi}[side]


class RoomPlanner:
    """Places furniture in one axis-aligned rectangular room."""

    def __init__(self, room: Room, openings: list[Opening], rng: np.random.Generator) -> None:
        self.room = room
        self.rng = rng
        lo, hi = room.polygon.min(axis=0), room.polygon.max(axis=0)
        inset = WALL_THICKNESS + WALL_GAP
        self.lo, self.hi = lo + inset, hi - inset
        self.placed: list[Placed] = []
        self.zones: list[np.ndarray] = []
        inner: list[np.ndarray] = []
        for o in openings:
            half = o.width / 2 + 0.1
            c = o.center
            if abs(c[1] - lo[1]) < 0.2 or abs(c[1] - hi[1]) < 0.2:  # on a south/north wall
                inward = np.array([0.0, 1.0 if abs(c[1] - lo[1]) < 0.2 else -1.0])
                along = np.array([half, 0.0])
            else:
                inward = np.array([1.0 if abs(c[0] - lo[0]) < 0.2 else -1.0, 0.0])
                along = np.array([0.0, half])
            self.zones.append(
                _segment_zone(c - inward * DOOR_CLEARANCE, c + inward * DOOR_CLEARANCE, along)
            )
            inner.append(c + inward * DOOR_CLEARANCE)
        # Rooms one passes through keep an L-shaped walkway between each pair of doors.
        for i in range(len(inner)):
            for j in range(i + 1, len(inner)):
                a, b = inner[i], inner[j]
                # Bend nearer the room centre, keeping the walls free for furniture.
                bends = [np.array([a[0], b[1]]), np.array([b[0], a[1]])]
                bend = min(bends, key=lambda q: float(np.linalg.norm(q - (lo + hi) / 2)))
                for p, q in ((a, bend), (bend, b)):
                    if np.linalg.norm(q - p) > 1e-6:
                        d = (q - p) / np.linalg.norm(q - p)
                        side = np.array([-d[1], d[0]]) * WALKWAY / 2
                        self.zones.append(
                            _segment_zone(p - d * WALKWAY / 2, q + d * WALKWAY / 2, side)
                        )

    @property
    def center(self) -> np.ndarray:  # [2]
        return (self.lo + self.hi) / 2

    def fits(self, candidate: Placed, margin: float = 0.05) -> bool:
        """Inside the room, clear of door zones and (unless flat) of other floor objects."""
        fp = candidate.footprint()
        if np.any(fp < self.lo - 1e-6) or np.any(fp > self.hi + 1e-6):
            return False
        if candidate.spec.flat:
            return True
        grown = candidate.footprint(margin)
        if any(rects_overlap(fp, z) for z in self.zones):
            return False
        return not any(
            rects_overlap(grown, p.footprint())
            for p in self.placed
            if not p.spec.flat and p.support is None and p.position[2] < candidate.top
        )

    def remove(self, placed: Placed) -> None:
        self.placed.remove(placed)

    def add(self, placed: Placed | None) -> Placed | None:
        if placed is not None:
            placed.key = len(self.placed)
            self.placed.append(placed)
        return placed

    def _wall_pose(self, side: str, along: float, depth: float) -> tuple[np.ndarray, float]:
        lo, hi = self.lo, self.hi
        xy = {
            "south": (along, lo[1] + depth / 2),
            "north": (along, hi[1] - depth / 2),
            "west": (lo[0] + depth / 2, along),
            "east": (hi[0] - depth / 2, along),
        }[side]
        return np.array([xy[0], xy[1], 0.0]), side_heading(side)

    def _along_range(self, side: str, width: float) -> tuple[float, float]:
        axis = 0 if side in ("south", "north") else 1
        return self.lo[axis] + width / 2, self.hi[axis] - width / 2

    def against_wall(
        self,
        spec: ObjectSpec,
        sides: tuple[str, ...] = SIDES,
        at: float | None = None,
        tries: int = 40,
        z: float = 0.0,
        margin: float = 0.05,
    ) -> Placed | None:
        """Back against one of `sides`, facing into the room (at `at` along it if given)."""
        for _ in range(tries if at is None else len(sides)):
            side = str(self.rng.choice(sides))
            a, b = self._along_range(side, spec.size[0])
            if a > b:
                continue
            along = float(np.clip(at, a, b)) if at is not None else float(self.rng.uniform(a, b))
            pos, heading = self._wall_pose(side, along, spec.size[1])
            pos[2] = z
            cand = Placed(spec, pos, heading, self.room.id, side=side)
            if self.fits(cand, margin):
                return self.add(cand)
        return None

    def facing(self, spec: ObjectSpec, target: Placed) -> Placed | None:
        """Against the wall across from `target`, centred on it, facing it."""
        opposite = {"south": "north", "north": "south", "east": "west", "west": "east"}
        side = opposite.get(target.side)
        if side is None:
            return None
        axis = 0 if side in ("south", "north") else 1
        for shift in (0.0, 0.3, -0.3, 0.6, -0.6):
            placed = self.against_wall(spec, (side,), at=float(target.position[axis]) + shift)
            if placed is not None:
                return placed
        return None

    def in_front_of(
        self, spec: ObjectSpec, anchor: Placed, distance: float, turn: float = math.pi
    ) -> Placed | None:
        """`distance` metres in front of `anchor`, turned by `turn` from its heading."""
        gap = anchor.spec.size[1] / 2 + distance + spec.size[1] / 2
        xy = anchor.position[:2] + anchor.front * gap
        cand = Placed(spec, np.array([xy[0], xy[1], 0.0]), anchor.heading + turn, self.room.id)
        return self.add(cand) if self.fits(cand) else None

    def beside(
        self, spec: ObjectSpec, anchor: Placed, side: int, gap: float = 0.08
    ) -> Placed | None:
        """Next to `anchor` on its left (+1) or right (-1), aligned with its back."""
        left = np.array([-anchor.front[1], anchor.front[0]])
        offset = side * (anchor.spec.size[0] / 2 + gap + spec.size[0] / 2)
        back = anchor.position[:2] - anchor.front * (anchor.spec.size[1] / 2)
        xy = back + left * offset + anchor.front * (spec.size[1] / 2)
        cand = Placed(spec, np.array([xy[0], xy[1], 0.0]), anchor.heading, self.room.id)
        cand.side = anchor.side
        return self.add(cand) if self.fits(cand) else None

    def around(
        self, spec: ObjectSpec, table: Placed, count: int, gap: float = 0.12
    ) -> list[Placed]:
        """Up to `count` chairs around a table, each facing its centre."""
        w, d = table.spec.size[0], table.spec.size[1]
        round_table = table.spec.attributes.get("shape") == "round"
        seats: list[tuple[np.ndarray, float]] = []
        if round_table:
            r = w / 2 + gap + spec.size[1] / 2 - 0.1
            start = float(self.rng.uniform(0, 2 * math.pi / max(count, 1)))
            for k in range(count):
                ang = start + 2 * math.pi * k / count
                seats.append((np.array([math.cos(ang), math.sin(ang)]) * r, ang + math.pi))
        else:
            per_side = max(1, min(count // 2, int(w // (spec.size[0] + 0.15))))
            for k in range(per_side):
                x = (k + 0.5) / per_side * w - w / 2
                for sy in (-1, 1):
                    y = sy * (d / 2 + gap + spec.size[1] / 2 - 0.12)
                    seats.append((np.array([x, y]), math.atan2(-sy, 0.0)))
            for sx in (-1, 1):
                x = sx * (w / 2 + gap + spec.size[1] / 2 - 0.12)
                seats.append((np.array([x, 0.0]), math.atan2(0.0, -sx)))
        rot = yaw_matrix(table.heading + math.pi / 2)[:2, :2]
        out: list[Placed] = []
        for local, local_heading in seats:
            if len(out) == count:
                break
            xy = table.position[:2] + rot @ local
            heading = local_heading + table.heading + math.pi / 2
            cand = Placed(spec, np.array([xy[0], xy[1], 0.0]), heading, self.room.id)
            if self._fits_except(cand, table):
                self.add(cand)
                out.append(cand)
        return out

    def _fits_except(self, cand: Placed, table: Placed) -> bool:
        """Chairs may tuck under their own table."""
        keep = self.placed
        self.placed = [p for p in keep if p is not table]
        try:
            return self.fits(cand, margin=0.02)
        finally:
            self.placed = keep

    def on_top(self, spec: ObjectSpec, support: Placed, jitter: float = 0.5) -> Placed | None:
        """On `support`'s top surface, within `jitter` of its free half-extent."""
        room_w = support.spec.size[0] - spec.size[0]
        room_d = support.spec.size[1] - spec.size[1]
        if room_w < 0 or room_d < 0:
            return None
        local = np.array(
            [
                self.rng.uniform(-1, 1) * room_w / 2 * jitter,
                self.rng.uniform(-1, 1) * room_d / 2 * jitter,
            ]
        )
        xy = support.position[:2] + yaw_matrix(support.heading + math.pi / 2)[:2, :2] @ local
        cand = Placed(
            spec, np.array([xy[0], xy[1], support.top]), support.heading, self.room.id, support
        )
        return self.add(cand)

    def corner(self, spec: ObjectSpec, tries: int = 8) -> Placed | None:
        """In a random free corner of the room."""
        for _ in range(tries):
            cx = (
                self.lo[0] + spec.size[0] / 2
                if self.rng.random() < 0.5
                else self.hi[0] - spec.size[0] / 2
            )
            cy = (
                self.lo[1] + spec.size[1] / 2
                if self.rng.random() < 0.5
                else self.hi[1] - spec.size[1] / 2
            )
            heading = math.atan2(self.center[1] - cy, self.center[0] - cx)
            heading = round(heading / (math.pi / 2)) * (math.pi / 2)
            cand = Placed(spec, np.array([cx, cy, 0.0]), heading, self.room.id)
            if self.fits(cand):
                return self.add(cand)
        return None

    def anywhere(self, spec: ObjectSpec, tries: int = 40) -> Placed | None:
        """At a random free spot, axis-aligned."""
        for _ in range(tries):
            x = self.rng.uniform(self.lo[0], self.hi[0])
            y = self.rng.uniform(self.lo[1], self.hi[1])
            heading = float(self.rng.integers(4)) * math.pi / 2
            cand = Placed(spec, np.array([x, y, 0.0]), heading, self.room.id)
            if self.fits(cand):
                return self.add(cand)
        return None

    def on_wall(self, spec: ObjectSpec, z: float, tries: int = 30) -> Placed | None:
        """Hung on a wall at height `z`, clear of doors and of taller furniture."""
        for _ in range(tries):
            side = str(self.rng.choice(SIDES))
            a, b = self._along_range(side, spec.size[0])
            if a > b:
                continue
            pos, heading = self._wall_pose(side, float(self.rng.uniform(a, b)), spec.size[1])
            pos[2] = z
            cand = Placed(spec, pos, heading, self.room.id, side=side)
            fp = cand.footprint(0.05)
            if any(rects_overlap(fp, zone) for zone in self.zones):
                continue
            if any(
                rects_overlap(fp, p.footprint()) and (p.top > z or p.position[2] >= z - 0.01)
                for p in self.placed
                if not p.spec.flat
            ):
                continue
            return self.add(cand)
        return None
