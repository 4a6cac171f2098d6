"""Numba kernel of `nav.footprint.in_clear_sight`: the lines from points to the nearest cell
of a unit, sampled as numpy sampled them (the same samples, so the same answers), reading
the blocking cells only where a line passes instead of masking the whole window.

The cells near the unit (within `tolerance` 4-neighbour steps, `ndimage.binary_dilation`'s
cross iterated: an L1 distance) are kept as each cell's L1 distance to the unit, capped,
on the unit's box grown by the tolerance.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def clear_sight(  # pragma: no cover - numba
    unit: np.ndarray,
    points: np.ndarray,
    state: np.ndarray,
    walls: np.ndarray,
    use_walls: bool,
    tolerance: int,
    room_tolerance: int,
    obstacle: int,
    room_level: int,
) -> np.ndarray:
    """[P] bool: whether the line from each of `points` [P, 2] (row, col) to its nearest cell
    of `unit` [K >= 1, 2] (cells inside `state`, first of equals) crosses no blocking cell.

    A cell blocks when `state` [H, W] holds `obstacle` there and, without walls, it is not
    near the unit (L1 distance > tolerance); with walls ([H, W] levels, `use_walls`), when
    walls > 0 and it is not near the unit, or walls >= room_level and it is farther than
    `room_tolerance`. Samples: n = ceil(4 sqrt(max squared distance)) + 2 per line, at
    `np.linspace(0, 1, n)`, rounded half to even and clipped to the window.
    """
    h, w = state.shape
    k = unit.shape[0]
    near = max(tolerance, 0)
    near_room = max(room_tolerance, 0)
    r0, r1, c0, c1 = unit[0, 0], unit[0, 0], unit[0, 1], unit[0, 1]
    for u in range(1, k):
        r0, r1 = min(r0, unit[u, 0]), max(r1, unit[u, 0])
        c0, c1 = min(c0, unit[u, 1]), max(c1, unit[u, 1])
    r0, c0 = max(r0 - near, 0), max(c0 - near, 0)
    r1, c1 = min(r1 + near + 1, h), min(c1 + near + 1, w)
    dist = np.full((r1 - r0, c1 - c0), near + 1, np.int64)
    for u in range(k):
        for dr in range(-near, near + 1):
            r = unit[u, 0] + dr
            if r < r0 or r >= r1:
                continue
            rest = near - abs(dr)
            for dc in range(-rest, rest + 1):
                c = unit[u, 1] + dc
                if c0 <= c < c1:
                    d = abs(dr) + abs(dc)
                    if d < dist[r - r0, c - c0]:
                        dist[r - r0, c - c0] = d
    p = points.shape[0]
    ends = np.empty(p, np.int64)
    farthest = np.int64(0)
    for i in range(p):
        best = np.int64(-1)
        for u in range(k):
            dr = points[i, 0] - unit[u, 0]
            dc = points[i, 1] - unit[u, 1]
            d2 = dr * dr + dc * dc
            if best < 0 or d2 < best:
                best = d2
                ends[i] = u
        farthest = max(farthest, best)
    n = int(math.ceil(math.sqrt(np.float64(farthest)) * 4)) + 2
    step = 1.0 / (n - 1)
    out = np.ones(p, np.bool_)
    for i in range(p):
        pr, pc = points[i, 0], points[i, 1]
        er, ec = unit[ends[i], 0], unit[ends[i], 1]
        for s in range(n):
            f = 1.0 if s == n - 1 else np.float64(s) * step + 0.0
            r = min(max(np.int64(np.rint(np.float64(pr) + f * np.float64(er - pr))), 0), h - 1)
            c = min(max(np.int64(np.rint(np.float64(pc) + f * np.float64(ec - pc))), 0), w - 1)
            if state[r, c] != obstacle:
                continue
            d = near + 1
            if r0 <= r < r1 and c0 <= c < c1:
                d = dist[r - r0, c - c0]
            if use_walls:
                level = walls[r, c]
                blocked = (level > 0 and d > near) or (level >= room_level and d > near_room)
            else:
                blocked = d > near
            if blocked:
                out[i] = False
                break
    return out
