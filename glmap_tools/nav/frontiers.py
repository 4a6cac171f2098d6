"""Frontiers (FBE): seen-free cells next to unknown space, reachable from the agent, clustered."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glmap_tools.map.occupancy import UNKNOWN, DenseOccupancy
from glmap_tools.nav.grid import agent_rc, clear_footprint, traversable

EIGHT_U8 = np.ones((3, 3), dtype=np.uint8)


@dataclass(frozen=True)
class Frontier:
    """One cluster of frontier cells.

    Attributes:
        centroid: (x, y) world metres, mean of the cells' centres.
        size: number of cells.
        cells: [K, 2] int (row, col) in the occupancy window the frontier was found in.
        distance: geodesic metres from the agent to the nearest of its cells (inf if unknown).
        target: (x, y) world metres of the frontier cell closest to the centroid (a navigable
            place to go; the centroid of a curved frontier may not be).
    """

    centroid: tuple[float, float]
    size: int
    cells: np.ndarray  # [K, 2]
    distance: float
    target: tuple[float, float]


def frontier_mask(occ: DenseOccupancy, trav: np.ndarray) -> np.ndarray:
    """[H, W] bool: traversable cells with an UNKNOWN cell among their 8 neighbours."""
    import cv2

    unknown = (occ.state == UNKNOWN).view(np.uint8)
    near_unknown = cv2.dilate(unknown, EIGHT_U8, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return trav & near_unknown.view(bool)


def _components(mask: np.ndarray, connectivity: int) -> tuple[np.ndarray, int]:
    """([H, W] int32 labels, count) of the connected True cells of `mask` (OpenCV; with
    connectivity 4 the labels are `ndimage.label`'s, in raster order of first cells)."""
    import cv2

    cells = np.ascontiguousarray(mask, dtype=bool).view(np.uint8)
    n, labels = cv2.connectedComponents(cells, connectivity=connectivity, ltype=cv2.CV_32S)
    return labels, int(n) - 1


def frontiers(
    occ: DenseOccupancy,
    agent_xy: tuple[float, float],
    agent_radius: float,
    min_size: int = 5,
    distance_field: np.ndarray | None = None,
    trav: np.ndarray | None = None,
) -> list[Frontier]:
    """Frontier clusters reachable from the agent through seen-free space, nearest first.

    Args:
        occ: dense occupancy window holding the agent.
        agent_xy: (x, y) metres.
        agent_radius: metres; obstacles are inflated by it, so a gap narrower than the agent
            closes and what lies behind it is not reachable.
        min_size: clusters with fewer cells are dropped (depth noise leaves tiny holes).
        distance_field: [H, W] geodesic metres from the agent over the same window (e.g. the
            planner's); when None, distances are straight-line metres to the nearest cell.
        trav: [H, W] `traversable(occ, agent_radius)` when the caller has it already.

    Raises:
        OutsideMapError: the agent is outside the window.
    """
    rc = agent_rc(occ, agent_xy)
    if trav is None:
        trav = traversable(occ, agent_radius)
    trav = clear_footprint(trav, rc, agent_radius / occ.cell_size)
    # 4-connected, as the FMM marches: a diagonal pinch is no way through.
    labels, _ = _components(trav, 4)
    reach = trav & (labels == labels[rc])
    fmask = frontier_mask(occ, reach)
    clusters, n = _components(fmask, 8)
    if n == 0:
        return []
    rows, cols = np.nonzero(clusters)
    ids = clusters[rows, cols]
    order = np.argsort(ids, kind="stable")
    rows, cols, ids = rows[order], cols[order], ids[order]
    starts = np.searchsorted(ids, np.arange(1, n + 1))
    ends = np.append(starts[1:], len(ids))
    s = occ.cell_size
    out = []
    for a, b in zip(starts, ends, strict=True):
        if b - a < min_size:
            continue
        cells = np.stack([rows[a:b], cols[a:b]], axis=1)
        mean = cells.mean(axis=0)
        centroid = (
            (float(mean[1]) + occ.origin[0] + 0.5) * s,
            (float(mean[0]) + occ.origin[1] + 0.5) * s,
        )
        k = int(np.argmin(((cells - mean) ** 2).sum(axis=1)))
        target = occ.index_to_world(int(cells[k, 0]), int(cells[k, 1]))
        if distance_field is not None:
            distance = float(distance_field[cells[:, 0], cells[:, 1]].min())
        else:
            distance = float(np.hypot(cells[:, 0] - rc[0], cells[:, 1] - rc[1]).min()) * s
        out.append(
            Frontier(
                centroid=(round(centroid[0], 4), round(centroid[1], 4)),
                size=int(b - a),
                cells=cells,
                distance=distance if math.isfinite(distance) else math.inf,
                target=target,
            )
        )
    # ties last by the first cell in raster order (the order of ndimage's labels)
    out.sort(key=lambda f: (f.distance, -f.size, f.centroid, tuple(f.cells[0].tolist())))
    return out
