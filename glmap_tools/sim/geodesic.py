"""Geodesic distances on an 8-connected grid: Dijkstra (numba) and a relaxation reference.

Moves go to the 8 neighbours (cost 1 or sqrt(2) cells); a diagonal move needs both cells it
passes between to be navigable (no cutting corners).
"""

from __future__ import annotations

import heapq
import math

import numpy as np
from numba import njit

_DR = np.array([-1, -1, -1, 0, 0, 1, 1, 1], dtype=np.int64)
_DC = np.array([-1, 0, 1, -1, 1, -1, 0, 1], dtype=np.int64)
_COST = np.array([math.sqrt(2), 1, math.sqrt(2), 1, 1, math.sqrt(2), 1, math.sqrt(2)])


@njit(cache=True)
def _dijkstra(
    navigable: np.ndarray, sources: np.ndarray, dr: np.ndarray, dc: np.ndarray, cost: np.ndarray
) -> np.ndarray:
    h, w = navigable.shape
    dist = np.full((h, w), np.inf)
    heap = [(0.0, 0)]
    heap.pop()
    for r in range(h):
        for c in range(w):
            if sources[r, c] and navigable[r, c]:
                dist[r, c] = 0.0
                heap.append((0.0, r * w + c))
    heapq.heapify(heap)
    while len(heap) > 0:
        d, idx = heapq.heappop(heap)
        r, c = idx // w, idx % w
        if d > dist[r, c]:
            continue
        for k in range(8):
            rr, cc = r + dr[k], c + dc[k]
            if rr < 0 or rr >= h or cc < 0 or cc >= w or not navigable[rr, cc]:
                continue
            if dr[k] != 0 and dc[k] != 0 and not (navigable[r, cc] and navigable[rr, c]):
                continue
            nd = d + cost[k]
            if nd < dist[rr, cc]:
                dist[rr, cc] = nd
                heapq.heappush(heap, (nd, rr * w + cc))
    return dist


def geodesic_distance(navigable: np.ndarray, sources: np.ndarray, cell: float) -> np.ndarray:
    """[H, W] shortest 8-connected path length (metres) to the nearest source; inf if none.

    Args:
        navigable: [H, W] bool cells one may stand on.
        sources: [H, W] bool goal cells (non-navigable ones are ignored).
        cell: cell side in metres.
    """
    nav = np.ascontiguousarray(navigable, dtype=np.bool_)
    src = np.ascontiguousarray(sources, dtype=np.bool_)
    return _dijkstra(nav, src, _DR, _DC, _COST) * cell


def warm_up() -> None:
    """Compile (or load from numba's cache) the Dijkstra kernel, which every episode's
    success distance needs (`glmap-mcp --prepare`, the server's warm-up)."""
    sources = np.zeros((3, 3), dtype=np.bool_)
    sources[1, 1] = True
    geodesic_distance(np.ones((3, 3), dtype=np.bool_), sources, 1.0)


def geodesic_distance_reference(
    navigable: np.ndarray, sources: np.ndarray, cell: float
) -> np.ndarray:
    """Slow reference: relax every cell from its 8 neighbours until nothing changes."""
    nav = np.asarray(navigable, dtype=bool)
    h, w = nav.shape
    dist = np.where(nav & sources, 0.0, np.inf)
    pad = np.pad(nav, 1)
    while True:
        padded = np.pad(dist, 1, constant_values=np.inf)
        best = dist.copy()
        for k in range(8):
            r, c = int(_DR[k]), int(_DC[k])
            neighbour = padded[1 + r : 1 + r + h, 1 + c : 1 + c + w]
            ok = nav & pad[1 + r : 1 + r + h, 1 + c : 1 + c + w]
            if r != 0 and c != 0:
                ok &= pad[1 : 1 + h, 1 + c : 1 + c + w] & pad[1 + r : 1 + r + h, 1 : 1 + w]
            best = np.where(ok, np.minimum(best, neighbour + _COST[k]), best)
        if np.array_equal(best, dist):
            return dist * cell
        dist = best
