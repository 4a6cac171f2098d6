"""The frame's geometric layers: floor height, occupancy, and the structure background layer."""

from __future__ import annotations

import numpy as np

from glmap_tools.gaussians.estimator import GaussianEstimator
from glmap_tools.map.config import MapConfig
from glmap_tools.map.frame_points import FramePoints, lattice
from glmap_tools.map.occupancy import OccupancyGrid
from glmap_tools.map.structure import ChunkKey, StructureChunk, StructureLayer
from glmap_tools.perception.semantics import FrameSemantics

FLOOR_PERCENTILE = 1.0
# Image columns the structure layer samples (with MapConfig.structure_stride = 0): at a
# 5 cm voxel 160 columns leave >= 9 points per voxel neighbourhood on a wall 3 m away.
STRUCTURE_COLUMNS = 160


def objects_mask(semantics: FrameSemantics, shape: tuple[int, int]) -> np.ndarray:
    """[H, W] bool: pixels in any object mask."""
    objects = np.zeros(shape, dtype=bool)
    for obj in semantics.objects:
        objects |= obj.mask
    return objects


def structure_mask(valid: np.ndarray, semantics: FrameSemantics) -> np.ndarray:
    """[H, W] bool: valid depth pixels in no object mask, nor next to one.

    Masks are grown by one pixel (4-neighbours): real depth mixes object and background at
    mask borders, and those pixels would leave a fringe of structure around every object.
    """
    objects = objects_mask(semantics, valid.shape)
    grown = objects.copy()
    grown[1:] |= objects[:-1]
    grown[:-1] |= objects[1:]
    grown[:, 1:] |= objects[:, :-1]
    grown[:, :-1] |= objects[:, 1:]
    return valid & ~grown


def structure_stride(config: MapConfig, width: int) -> int:
    """The structure layer's pixel stride for images `width` pixels wide."""
    return config.structure_stride or max(1, round(width / STRUCTURE_COLUMNS))


def needed_pixels(
    config: MapConfig, semantics: FrameSemantics, shape: tuple[int, int]
) -> np.ndarray:
    """[H, W] bool: the pixels occupancy, structure and the object masks read."""
    needed = lattice(shape, config.occupancy_stride) | objects_mask(semantics, shape)
    if config.structure_voxel is not None:
        needed |= lattice(shape, structure_stride(config, shape[1]))
    return needed


def frame_floor(points: np.ndarray, map_floor_z: float | None) -> float:
    """The floor height: the FLOOR_PERCENTILE of the frame's heights, or the map's if lower.

    Args:
        points: [N, 3] world points of the frame's valid depth (N > 0).
        map_floor_z: the map's floor so far (None before the first frame).
    """
    frame_z = float(np.percentile(points[:, 2], FLOOR_PERCENTILE))
    return frame_z if map_floor_z is None else min(map_floor_z, frame_z)


def plan_occupancy(
    occupancy: OccupancyGrid,
    camera_xy: np.ndarray,
    points: FramePoints,
    config: MapConfig,
    map_floor_z: float | None,
) -> tuple[float | None, dict[tuple[int, int], np.ndarray]]:
    """(floor height, updated occupancy chunks) from the frame's valid depth.

    A frame whose valid depth misses the occupancy lattice (only a masked object's pixels,
    say) changes no cell and leaves the floor as it was (None before any frame set it).

    Args:
        occupancy: the map's occupancy grid (not changed).
        camera_xy: [2] camera position, metres.
        points: the frame's points.
        config: the map's settings (occupancy stride, floor, obstacle band).
        map_floor_z: the map's floor so far.
    """
    cloud = points.cloud(stride=config.occupancy_stride)
    floor_z = config.floor_z
    if len(cloud.points) == 0:
        return (map_floor_z if floor_z is None else floor_z), {}
    if floor_z is None:
        floor_z = frame_floor(cloud.points, map_floor_z)
    update = occupancy.compute_update(camera_xy, cloud.points, floor_z, config.obstacle_band)
    return floor_z, update


def plan_structure(
    structure: StructureLayer,
    estimator: GaussianEstimator,
    points: FramePoints,
    semantics: FrameSemantics,
    config: MapConfig,
) -> tuple[dict[ChunkKey, StructureChunk], int]:
    """(updated structure chunks, Gaussians fitted) for the frame's structure pixels.

    Args:
        structure: the map's structure layer (not changed).
        estimator: the structure estimator (one Gaussian per coarse voxel).
        points: the frame's points.
        semantics: the frame's objects (their pixels are no structure).
        config: the map's settings (structure voxel and stride).
    """
    if config.structure_voxel is None:
        return {}, 0
    stride = structure_stride(config, points.valid.shape[1])
    cloud = points.cloud(structure_mask(points.valid, semantics), stride)
    fitted = estimator.fit(cloud.points, cloud.colors)
    return structure.compute_update(fitted), len(fitted)
