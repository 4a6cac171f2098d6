"""Named colours and materials: what attributes say and what the renderer paints."""

from __future__ import annotations

COLORS: dict[str, tuple[float, float, float]] = {
    "red": (0.78, 0.16, 0.14),
    "orange": (0.92, 0.5, 0.12),
    "yellow": (0.93, 0.8, 0.2),
    "green": (0.22, 0.55, 0.25),
    "teal": (0.1, 0.5, 0.5),
    "blue": (0.16, 0.3, 0.75),
    "navy": (0.1, 0.14, 0.38),
    "purple": (0.45, 0.2, 0.55),
    "pink": (0.92, 0.55, 0.65),
    "brown": (0.45, 0.28, 0.15),
    "beige": (0.86, 0.78, 0.62),
    "white": (0.93, 0.93, 0.91),
    "grey": (0.5, 0.5, 0.52),
    "black": (0.1, 0.1, 0.11),
}

# Colours of the "frame" parts (legs, wooden frames) for each material attribute.
MATERIALS: dict[str, tuple[float, float, float]] = {
    "wood": (0.62, 0.42, 0.24),
    "oak": (0.74, 0.56, 0.35),
    "walnut": (0.36, 0.23, 0.14),
    "metal": (0.62, 0.64, 0.67),
    "steel": (0.7, 0.72, 0.75),
    "plastic": (0.88, 0.88, 0.86),
    "ceramic": (0.95, 0.95, 0.95),
    "fabric": (0.62, 0.42, 0.24),
    "leather": (0.36, 0.23, 0.14),
    "velvet": (0.36, 0.23, 0.14),
    "marble": (0.9, 0.9, 0.88),
    "glass": (0.75, 0.85, 0.88),
}

DARK = (0.08, 0.08, 0.09)
LIGHT = (0.95, 0.95, 0.94)

# Wall and floor colours of generated apartments (distinct per room).
WALL_COLORS: list[tuple[float, float, float]] = [
    (0.93, 0.91, 0.86),
    (0.82, 0.88, 0.92),
    (0.9, 0.84, 0.78),
    (0.85, 0.9, 0.82),
    (0.95, 0.88, 0.88),
    (0.88, 0.86, 0.94),
    (0.8, 0.8, 0.78),
    (0.96, 0.93, 0.8),
]
FLOOR_COLORS: dict[str, tuple[float, float, float]] = {
    "light oak parquet": (0.72, 0.56, 0.38),
    "dark wood floor": (0.4, 0.27, 0.17),
    "grey tiles": (0.55, 0.56, 0.58),
    "white tiles": (0.86, 0.86, 0.84),
    "beige carpet": (0.78, 0.7, 0.58),
    "terracotta tiles": (0.7, 0.4, 0.28),
    "blue-grey vinyl": (0.45, 0.5, 0.58),
}
