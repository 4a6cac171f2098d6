"""The occupancy grid's per-frame update against a plain, per-point reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools.map.occupancy import BEARING_BIN, CHUNK, OccupancyGrid

BAND = (0.10, 1.50)


def plain_update(grid: OccupancyGrid, camera: np.ndarray, points: np.ndarray, floor_z: float):
    """Each cell once a frame: blocked where an obstacle point is; else free where a floor
    point is or a free ray passes (per 0.5-degree bearing, from the camera to one cell
    short of its nearest obstacle point, or of its farthest point, in half-cell steps)."""
    s = grid.cell_size
    free, blocked = set(), set()
    reach: dict[int, float] = {}
    nearest: dict[int, float] = {}
    for x, y, z in points.tolist():
        cell = (math.floor(x / s), math.floor(y / s))
        h = z - floor_z
        if BAND[0] <= h <= BAND[1]:
            blocked.add(cell)
        elif abs(h) < BAND[0]:
            free.add(cell)
        dx, dy = x - camera[0], y - camera[1]
        b = math.floor(math.atan2(dy, dx) / BEARING_BIN)
        reach[b] = max(reach.get(b, 0.0), math.hypot(dx, dy))
        if BAND[0] <= h <= BAND[1]:
            nearest[b] = min(nearest.get(b, math.inf), math.hypot(dx, dy))
    for b, far in reach.items():
        length = min(far, nearest.get(b, math.inf)) - s
        angle = (b + 0.5) * BEARING_BIN
        for k in range(int(length / (s / 2)) + 1 if length > 0 else 0):
            t = k * (s / 2)
            free.add(
                (
                    math.floor((camera[0] + t * math.cos(angle)) / s),
                    math.floor((camera[1] + t * math.sin(angle)) / s),
                )
            )
    out: dict[tuple[int, int], np.ndarray] = {}
    for layer, cells in ((0, free - blocked), (1, blocked)):
        for i, j in cells:
            key = (i // CHUNK, j // CHUNK)
            if key not in out:
                old = grid.chunks.get(key)
                out[key] = np.zeros((2, CHUNK, CHUNK), np.int32) if old is None else old.copy()
            out[key][layer, j - key[1] * CHUNK, i - key[0] * CHUNK] += 1
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_update_equals_the_plain_reference(seed):
    rng = np.random.default_rng(seed)
    grid = OccupancyGrid(0.05)
    for frame in range(3):
        camera = rng.uniform(-3.0, 3.0, 2)  # chunks on both sides of zero
        n = 3000
        heading = rng.uniform(-np.pi, np.pi)
        angle = heading + rng.uniform(-0.8, 0.8, n)
        dist = rng.uniform(0.3, 4.0, n)
        z = np.where(rng.random(n) < 0.5, rng.normal(0.0, 0.03, n), rng.uniform(-0.2, 2.0, n))
        points = np.stack(
            [camera[0] + dist * np.cos(angle), camera[1] + dist * np.sin(angle), z], 1
        )
        update = grid.compute_update(camera, points, 0.0, BAND)
        expected = plain_update(grid, camera, points, 0.0)
        assert sorted(update) == sorted(expected)
        for key, counts in update.items():
            np.testing.assert_array_equal(counts, expected[key], err_msg=f"frame {frame}, {key}")
        grid.apply(update)
    assert any(c[1].any() for c in grid.chunks.values()) and any(
        c[0].any() for c in grid.chunks.values()
    )


def test_a_frame_changes_only_the_copies_it_returns():
    grid = OccupancyGrid(0.05)
    camera = np.zeros(2)
    points = np.array([[1.0, 0.0, 0.5], [1.0, 0.2, 0.0], [-2.0, -1.0, 0.0]])
    first = grid.compute_update(camera, points, 0.0, BAND)
    grid.apply(first)
    before = {k: v.copy() for k, v in grid.chunks.items()}
    second = grid.compute_update(camera, points, 0.0, BAND)
    assert all(np.array_equal(grid.chunks[k], before[k]) for k in before)
    assert all(np.array_equal(second[k], 2 * before[k]) for k in before)
    assert grid.compute_update(camera, np.zeros((0, 3)), 0.0, BAND) == {}
