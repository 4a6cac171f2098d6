"""Comparisons answered from the map: nearer, bigger, taller, from the units' Gaussians.

"Which is closer to me, the sofa or the table?" compares distances from the pose to each
unit's nearest grid cell; "is the bed bigger than the desk?" the volumes of the units'
extents (length x width x height of their Gaussians' means, `surroundings.gaussian_size`);
"taller/shorter" their heights, "higher/lower" their tops. Each object is the nearest unit
of its label (in the place the question gives it: "the chair on my left"). A difference
smaller than the margin (MARGINS) is too close to call from a map and is said so
(supported=False) rather than guessed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from glmap_tools.sqa.egocentric import pick, split_ego
from glmap_tools.sqa.records import MapAnswer
from glmap_tools.sqa.surroundings import Nearby, Surroundings

Match = Callable[[str, Sequence[str]], "str | None"]
# rel -> (measure, larger wins)
RELATIONS = {
    "closer": ("distance", False),
    "nearer": ("distance", False),
    "farther": ("distance", True),
    "further": ("distance", True),
    "bigger": ("volume", True),
    "larger": ("volume", True),
    "heavier": ("volume", True),
    "smaller": ("volume", False),
    "wider": ("length", True),
    "longer": ("length", True),
    "taller": ("height", True),
    "shorter": ("height", False),
    "higher": ("top", True),
    "lower": ("top", False),
}
# A difference under these is too close to call: metres for distance, length, height and
# top; a ratio for volume.
MARGINS = {"distance": 0.3, "length": 0.15, "height": 0.15, "top": 0.15, "volume": 1.3}


def measure(n: Nearby, what: str) -> float:
    """A unit's distance, volume (m^3), length, height or top (m)."""
    if what == "distance":
        return n.distance
    if what == "top":
        return n.z_max
    size = n.size or (
        max(n.footprint[2] - n.footprint[0], n.footprint[3] - n.footprint[1]),
        min(n.footprint[2] - n.footprint[0], n.footprint[3] - n.footprint[1]),
        n.z_max - n.z_min,
    )
    if what == "length":
        return size[0]
    if what == "height":
        return size[2]
    return size[0] * size[1] * max(size[2], 0.05)


def compare(
    parts: dict[str, str], where: Surroundings, near: Sequence[Nearby], match: Match
) -> MapAnswer:
    """The answer to a comparison: the winner's name as asked ("which ...?") or yes/no
    ("is the X ... than the Y?")."""
    kind = "compare"
    what, larger = RELATIONS[parts["rel"]]
    labels = list(where.labels.values())
    units = []
    for key in ("a", "b"):
        phrase = parts[key]
        label = match(phrase, labels)
        unit = pick(near, label, phrase) if label else None
        if unit is None:
            return MapAnswer("", kind, False, f"no {phrase!r} nearby")
        units.append(unit)
    a, b = units
    va, vb = measure(a, what), measure(b, what)
    if what == "volume":
        close = max(va, vb) < MARGINS[what] * max(min(va, vb), 1e-6)
    else:
        close = abs(va - vb) < MARGINS[what]
    why = f"{what}: unit {a.unit_id} {va:.2f}, unit {b.unit_id} {vb:.2f}"
    if close:
        return MapAnswer("", kind, False, f"too close to call from the map ({why})")
    a_wins = (va > vb) == larger
    if "which" in parts:
        return MapAnswer(split_ego(parts["a" if a_wins else "b"])[0], kind, True, why)
    return MapAnswer("yes" if a_wins else "no", kind, True, why)
