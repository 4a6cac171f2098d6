"""Small synthetic maps shared by the views tests (no tests here)."""

from __future__ import annotations

from dataclasses import dataclass

from glmap_tools import synthetic as scenes
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig

CHAIR_XY = (0.0, 0.7)
WALL_Y = 0.0  # the wall's plane; the chair stands on its +y (open) side
TEXTS = {
    1: ("chair", "a red chair with wooden legs"),
    2: ("wall", "a long white wall"),
    3: ("table", "a brown wooden table"),
}
# Three cameras on the open side and three behind the wall, so free space is seen on both.
OPEN_SIDE = [(0.0, 2.6), (1.6, 2.2), (-1.6, 2.2)]
WALL_SIDE = [(0.0, -2.4), (1.5, -2.2), (-1.5, -2.2)]


@dataclass
class WallScene:
    """A map of a chair behind a wall, with its ids."""

    glmap: GLMap
    chair: int
    walls: tuple[int, ...]
    region: int | None


def wall_boxes() -> list[scenes.Box]:
    wall = scenes.Box((-2.0, WALL_Y - 0.05, 0.0), (2.0, WALL_Y + 0.05, 1.6), (0.85, 0.85, 0.8), 2)
    return scenes.floor(4.0) + [wall] + scenes.chair(*CHAIR_XY)


def build_wall_scene(width: int = 160, height: int = 120) -> WallScene:
    """Integrate six ray-cast frames of the chair-behind-a-wall scene into a new map.

    Frames from the open side also report a region "reading corner" holding the chair.
    """
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    boxes = wall_boxes()
    texts = {k: v for k, v in TEXTS.items() if k in (1, 2)}
    for x, y in OPEN_SIDE:
        frame, ids = scenes.view(boxes, (x, y, 1.2), (*CHAIR_XY, 0.3), width, height)
        groups = [(5, "a reading corner with a red chair by the wall", (1,))]
        glmap.integrate(frame, scenes.semantics(ids, texts, groups))
    for x, y in WALL_SIDE:
        frame, ids = scenes.view(boxes, (x, y, 1.2), (0.0, WALL_Y, 0.5), width, height)
        glmap.integrate(frame, scenes.semantics(ids, texts))
    chair = next(u.id for u in glmap.instances.values() if u.label == "chair")
    walls = tuple(sorted(u.id for u in glmap.instances.values() if u.label == "wall"))
    region = next(iter(sorted(glmap.regions)), None)
    return WallScene(glmap, chair, walls, region)


def empty_map() -> GLMap:
    return GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
