"""Object geometry: catalog meshes in their unit frame, coloured and placed in the world."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np
import trimesh

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.adapters import ZUP_FROM_YUP
from glmap_tools.sim.catalog import MeshSpec, mesh_spec
from glmap_tools.sim.layout import SceneObject
from glmap_tools.sim.palette import COLORS, DARK, LIGHT, MATERIALS
from glmap_tools.sim.primitives import BUILDERS

FURNITURE_DIR = "data/furniture"
DEFAULT_PRIMITIVE_COLOR = (0.8, 0.8, 0.78)


@dataclass(frozen=True)
class MeshPart:
    """One single-material piece of a catalog mesh in the unit frame.

    Attributes:
        vertices: [N, 3] float64 in x, y in [-0.5, 0.5], z in [0, 1]; the front faces -y.
        faces: [M, 3] int64 vertex indices.
        material: Kenney material name or primitive part name.
        color: default RGB in [0, 1].
    """

    vertices: np.ndarray  # [N, 3]
    faces: np.ndarray  # [M, 3]
    material: str
    color: tuple[float, float, float]


@dataclass(frozen=True)
class PlacedPart:
    """A coloured triangle mesh in world coordinates (metres, z up)."""

    vertices: np.ndarray  # [N, 3]
    faces: np.ndarray  # [M, 3]
    color: tuple[float, float, float]


def _kenney_meshes(model: str) -> list[tuple[trimesh.Trimesh, str, tuple[float, float, float]]]:
    ref = resources.files("glmap_tools").joinpath(f"{FURNITURE_DIR}/{model}.glb")
    if not ref.is_file():
        raise InvalidInputError(
            f"furniture model {model}.glb is missing from the package data ({FURNITURE_DIR}); "
            "reinstall glmap-tools."
        )
    with resources.as_file(ref) as path:
        scene = trimesh.load(str(path), force="scene")
    assert isinstance(scene, trimesh.Scene)
    out = []
    to_zup = np.eye(4)
    to_zup[:3, :3] = ZUP_FROM_YUP
    for node in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[node]
        geom = scene.geometry[geometry_name]
        mesh = trimesh.Trimesh(vertices=geom.vertices, faces=geom.faces, process=False)
        mesh.apply_transform(to_zup @ transform)
        material = geom.visual.material
        factor = getattr(material, "baseColorFactor", None)
        rgba = np.asarray((200, 200, 200, 255) if factor is None else factor)
        rgb = rgba[:3].astype(np.float64) / (255.0 if rgba.dtype == np.uint8 else 1.0)
        out.append((mesh, str(getattr(material, "name", "")), (rgb[0], rgb[1], rgb[2])))
    return out


def _primitive_color(part: str) -> tuple[float, float, float]:
    return {"dark": DARK, "light": LIGHT, "frame": MATERIALS["wood"]}.get(
        part, DEFAULT_PRIMITIVE_COLOR
    )


@cache
def unit_parts(name: str) -> tuple[MeshPart, ...]:
    """The parts of catalog mesh `name`, normalised to the unit frame (cached)."""
    spec = mesh_spec(name)
    if spec.is_kenney:
        raw = _kenney_meshes(spec.model)
    else:
        raw = [(m, part, _primitive_color(part)) for m, part in BUILDERS[spec.model]()]
    lo = np.min([m.bounds[0] for m, _, _ in raw], axis=0)
    hi = np.max([m.bounds[1] for m, _, _ in raw], axis=0)
    center = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    scale = np.maximum(hi - lo, 1e-6)
    parts = []
    for mesh, material, color in raw:
        vertices = (np.asarray(mesh.vertices, dtype=np.float64) - center) / scale
        parts.append(MeshPart(vertices, np.asarray(mesh.faces, dtype=np.int64), material, color))
    return tuple(parts)


def object_color(obj: SceneObject) -> tuple[float, float, float] | None:
    """The RGB its tinted parts are painted: `color`, else the named colour attribute."""
    if obj.color is not None:
        return obj.color
    return COLORS.get(obj.attributes.get("color", "").lower())


def part_color(obj: SceneObject, spec: MeshSpec, part: MeshPart) -> tuple[float, float, float]:
    """Colour of one part of `obj`: tinted parts take the object's colour, frames its material."""
    tint = object_color(obj)
    frame = MATERIALS.get(obj.attributes.get("material", "").lower())
    if part.material in spec.tint:
        return tint or frame or part.color
    is_frame = part.material == "frame" or (spec.is_kenney and part.material.startswith("wood"))
    if is_frame and frame is not None:
        return frame
    return part.color


def object_parts(obj: SceneObject) -> list[PlacedPart]:
    """The world-frame coloured meshes of one layout object."""
    spec = mesh_spec(obj.mesh)
    rotation = obj.rotation
    out = []
    for part in unit_parts(obj.mesh):
        vertices = (part.vertices * obj.size) @ rotation.T + obj.position
        out.append(PlacedPart(vertices, part.faces, part_color(obj, spec, part)))
    return out
