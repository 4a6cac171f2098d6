"""Render targets: one instance, a region, a subset of units or the whole map, from a pose.

Every function validates its inputs once (unit ids, pose, image size) and raises a
`GLMapError` naming the bad value and the fix before any work is done.

Whenever the map is drawn (the whole map, a unit in context) its structure background
layer (walls, floor) is drawn with it, so a wall hides what stands behind it; a unit or a
subset drawn alone leaves it out, as the paper shows a unit. `structure=` overrides both.
"""

from __future__ import annotations

import math
import numbers
import threading
import weakref
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.render import render
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.views.common import (
    WHITE,
    RenderedView,
    as_pose,
    check_intrinsics,
    check_unit_id,
    require_instances,
    view_intrinsics,
)

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

_cache_lock = threading.Lock()
_cache: weakref.WeakKeyDictionary[GLMap, MapGaussians] = weakref.WeakKeyDictionary()
_scene_cache: weakref.WeakKeyDictionary[GLMap, tuple[GaussianSet, GaussianSet, GaussianSet]] = (
    weakref.WeakKeyDictionary()
)


# ---------------------------------------------------------------------- Gaussians of targets


@dataclass(frozen=True)
class MapGaussians:
    """All instance Gaussians of a map in one set, with each instance's slice.

    Attributes:
        units: the instance units concatenated, in increasing id order.
        gaussians: their Gaussians, in the same order.
        slices: instance id -> (start, stop) rows of `gaussians`.
    """

    units: tuple[InstanceUnit, ...]
    gaussians: GaussianSet
    slices: dict[int, tuple[int, int]]

    def mask_of(self, instance_ids: Iterable[int]) -> np.ndarray:
        """[N] bool: the rows of the given instances."""
        mask = np.zeros(len(self.gaussians), dtype=bool)
        for iid in instance_ids:
            start, stop = self.slices[iid]
            mask[start:stop] = True
        return mask

    def matches(self, glmap: GLMap) -> bool:
        """Whether the map still holds exactly these (immutable) instance units."""
        if len(glmap.instances) != len(self.units):
            return False
        return all(glmap.instances.get(u.id) is u for u in self.units)


def map_gaussians(glmap: GLMap) -> MapGaussians:
    """Every instance's Gaussians in one set, cached until an instance changes.

    Units are immutable and replaced on update, so the cache holds the unit objects and is
    valid while the map holds the very same ones.
    """
    with _cache_lock:
        cached = _cache.get(glmap)
    if cached is not None and cached.matches(glmap):
        return cached
    units = tuple(glmap.instances[i] for i in sorted(glmap.instances))
    slices, start = {}, 0
    for u in units:
        slices[u.id] = (start, start + len(u.gaussians))
        start += len(u.gaussians)
    result = MapGaussians(units, GaussianSet.concat([u.gaussians for u in units]), slices)
    with _cache_lock:
        _cache[glmap] = result
    return result


def structure_gaussians(glmap: GLMap) -> GaussianSet:
    """The map's structure background layer (walls, floor): never a unit, always occluding."""
    return glmap.structure.gaussians()


def scene_gaussians(glmap: GLMap, structure: bool = True) -> GaussianSet:
    """Every instance's Gaussians, then (with `structure`) the structure layer's; cached."""
    units = map_gaussians(glmap).gaussians
    if not structure or len(glmap.structure) == 0:
        return units
    background = structure_gaussians(glmap)
    with _cache_lock:
        cached = _scene_cache.get(glmap)
    if cached is not None and cached[0] is units and cached[1] is background:
        return cached[2]
    both = GaussianSet.concat([units, background])
    with _cache_lock:
        _scene_cache[glmap] = (units, background, both)
    return both


def with_structure(glmap: GLMap, gaussians: GaussianSet, structure: bool) -> GaussianSet:
    """`gaussians` plus the structure layer when `structure` is True."""
    if not structure or len(glmap.structure) == 0:
        return gaussians
    return GaussianSet.concat([gaussians, structure_gaussians(glmap)])


def require_drawable(glmap: GLMap, structure: bool) -> None:
    """Raise InvalidInputError unless the map has instances, or structure to draw."""
    if not (structure and len(glmap.structure)):
        require_instances(glmap)


def instance_ids_of(glmap: GLMap, unit_id: int) -> tuple[int, ...]:
    """The instance ids a unit stands for: itself, or a region's members (sorted).

    Raises:
        InvalidInputError: a non-integer id, or a region none of whose instances exist.
        UnknownIdError: no such unit (the message suggests the closest id).
    """
    unit = glmap.unit(check_unit_id(unit_id))
    if isinstance(unit, InstanceUnit):
        return (unit.id,)
    assert isinstance(unit, RegionUnit)
    members = tuple(sorted(i for i in unit.instance_ids if i in glmap.instances))
    if not members:
        raise InvalidInputError(f"region {unit.id} has no instances left to draw.")
    return members


def subset_instance_ids(glmap: GLMap, unit_ids: Sequence[int]) -> tuple[int, ...]:
    """The sorted union of the instance ids of several units (regions expand to members)."""
    if isinstance(unit_ids, str | bytes) or not isinstance(unit_ids, Sequence | set | frozenset):
        raise InvalidInputError(
            f"unit_ids={unit_ids!r} must be a list of integer unit ids, e.g. [3, 7]."
        )
    if len(unit_ids) == 0:
        raise InvalidInputError("unit_ids is empty; give at least one instance or region id.")
    ids: set[int] = set()
    for uid in unit_ids:
        ids.update(instance_ids_of(glmap, uid))
    return tuple(sorted(ids))


def gaussians_of(glmap: GLMap, instance_ids: Iterable[int]) -> GaussianSet:
    """The union of the given instances' Gaussians (from the cached map set)."""
    cached = map_gaussians(glmap)
    return cached.gaussians.subset(cached.mask_of(instance_ids))


def unit_gaussians(glmap: GLMap, unit_id: int) -> GaussianSet:
    """An instance's Gaussians, or the union of a region's instances' Gaussians."""
    return gaussians_of(glmap, instance_ids_of(glmap, unit_id))


def unit_label(glmap: GLMap, unit_id: int) -> str:
    """'instance 3 (chair)' or 'region 9'."""
    unit = glmap.unit(check_unit_id(unit_id))
    if isinstance(unit, InstanceUnit):
        return f"instance {unit.id} ({unit.label})" if unit.label else f"instance {unit.id}"
    return f"region {unit.id}"


# ---------------------------------------------------------------------- rendering


def render_gaussians(
    gaussians: GaussianSet,
    pose: Pose | np.ndarray,
    intrinsics: Intrinsics,
    *,
    label: str = "view",
    background: Sequence[float] = WHITE,
    return_depth: bool = False,
) -> RenderedView:
    """Splat any GaussianSet into a `RenderedView` (validating the pose and the size caps)."""
    pose = as_pose(pose)
    check_intrinsics(intrinsics)
    result = render(
        gaussians,
        pose,
        intrinsics,
        background=background,
        return_depth=return_depth,
        return_alpha=True,
    )
    assert result.alpha is not None
    return RenderedView(label, result.to_uint8(), result.alpha, pose, intrinsics, result.depth)


def render_map(
    glmap: GLMap,
    pose: Pose | np.ndarray,
    intrinsics: Intrinsics,
    *,
    background: Sequence[float] = WHITE,
    return_depth: bool = False,
    structure: bool = True,
) -> RenderedView:
    """Render every instance of the map, and its structure layer, from `pose`.

    Args:
        structure: also draw the structure background layer (walls, floor).

    Raises:
        InvalidInputError: an empty map, a non-rigid pose or an image over the caps.
    """
    pose = as_pose(pose)
    check_intrinsics(intrinsics)
    require_drawable(glmap, structure)
    return render_gaussians(
        scene_gaussians(glmap, structure),
        pose,
        intrinsics,
        label="whole map",
        background=background,
        return_depth=return_depth,
    )


def overview_pose(
    glmap: GLMap, intrinsics: Intrinsics | None = None, elevation_deg: float = 50.0
) -> Pose:
    """A camera above the map that frames all of it, from the side the map was observed.

    It looks at the centre of the map's robust bounds (1st-99th percentile of the
    Gaussian means) from `elevation_deg` above the horizon, on the side of the mean
    trajectory camera (-y when there is none), far enough that the bounding sphere fits
    the narrower field of view with 10 % to spare.

    Raises:
        InvalidInputError: an empty map, bad intrinsics or an elevation outside [0, 90).
    """
    intrinsics = check_intrinsics(intrinsics) if intrinsics is not None else view_intrinsics()
    if not (isinstance(elevation_deg, numbers.Real) and 0.0 <= float(elevation_deg) < 90.0):
        raise InvalidInputError(f"elevation_deg={elevation_deg!r} must be in [0, 90) degrees.")
    require_instances(glmap)
    means = map_gaussians(glmap).gaussians.means.astype(np.float64)
    lo, hi = np.percentile(means, 1, axis=0), np.percentile(means, 99, axis=0)
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 0.5)
    half_fov = min(
        math.atan(intrinsics.width / (2.0 * intrinsics.fx)),
        math.atan(intrinsics.height / (2.0 * intrinsics.fy)),
    )
    distance = 1.1 * radius / math.sin(half_fov)
    side = np.array([0.0, -1.0])
    if glmap.trajectory:
        mean_eye = np.mean([m[:2, 3] for m in glmap.trajectory], axis=0) - center[:2]
        if float(np.linalg.norm(mean_eye)) > 1e-6:
            side = mean_eye / np.linalg.norm(mean_eye)
    el = math.radians(float(elevation_deg))
    eye = center + distance * np.array(
        [math.cos(el) * side[0], math.cos(el) * side[1], math.sin(el)]
    )
    return Pose.looking_at(eye, center)


def render_unit(
    glmap: GLMap,
    unit_id: int,
    pose: Pose | np.ndarray,
    intrinsics: Intrinsics,
    *,
    context: bool = False,
    background: Sequence[float] = WHITE,
    return_depth: bool = False,
    structure: bool | None = None,
) -> RenderedView:
    """Render one instance, or a region (the union of its instances' Gaussians), from `pose`.

    Args:
        glmap: the map.
        unit_id: an instance or region id.
        pose: world_from_camera (Pose or 4x4 matrix).
        intrinsics: the camera (see `view_intrinsics`).
        context: False draws only the unit's Gaussians (as the paper shows a unit); True
            draws the whole map from the same camera.
        background: RGB in [0, 1] behind the Gaussians.
        return_depth: also return the expected-depth image.
        structure: also draw the structure background layer (walls, floor), which hides
            the unit where a wall stands between it and the camera; None = as `context`.

    Raises:
        UnknownIdError: no such unit (with the closest id).
        InvalidInputError: a bad id, pose or image size.
    """
    pose = as_pose(pose)
    check_intrinsics(intrinsics)
    ids = instance_ids_of(glmap, unit_id)
    label = unit_label(glmap, unit_id)
    structure = context if structure is None else structure
    if context:
        g = scene_gaussians(glmap, structure)
    else:
        g = with_structure(glmap, gaussians_of(glmap, ids), structure)
    return render_gaussians(
        g, pose, intrinsics, label=label, background=background, return_depth=return_depth
    )


def render_subset(
    glmap: GLMap,
    unit_ids: Sequence[int],
    pose: Pose | np.ndarray,
    intrinsics: Intrinsics,
    *,
    background: Sequence[float] = WHITE,
    return_depth: bool = False,
    structure: bool = False,
) -> RenderedView:
    """Render the union of several units' Gaussians (regions expand to their instances);
    `structure=True` adds the structure background layer (walls, floor)."""
    pose = as_pose(pose)
    check_intrinsics(intrinsics)
    ids = subset_instance_ids(glmap, unit_ids)
    return render_gaussians(
        with_structure(glmap, gaussians_of(glmap, ids), structure),
        pose,
        intrinsics,
        label="units " + ", ".join(str(i) for i in ids),
        background=background,
        return_depth=return_depth,
    )
