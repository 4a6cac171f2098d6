"""FMM geodesic distance, path by descent, and the next discrete action.

`geodesic` solves the eikonal equation |grad T| = 1 from a source cell over the plannable
cells (isotropic, second order; `_fmm_numba`, scikit-fmm's `travel_time` to the bit).
`reference_geodesic` is Dijkstra on the 8-connected grid (scipy.sparse.csgraph): it can
only move in 8 directions, so it overestimates a straight line at angle a from an axis by
(cos a + (sqrt 2 - 1) sin a), at most 8.24 % at 22.5 deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from glmap_tools.map.occupancy import DenseOccupancy
from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.errors import UnreachableGoalError
from glmap_tools.nav.grid import agent_rc
from glmap_tools.nav.motion import clearance, drive, masks

# Dijkstra-8 / true length lies in [1, DIJKSTRA8_MAX_RATIO] for a straight, free path.
DIJKSTRA8_MAX_RATIO = math.cos(math.pi / 8) + (math.sqrt(2) - 1) * math.sin(math.pi / 8)
_STEPS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]
# The cost-to-go's band: the cost at the agent lay within 0.89-1.14 x the agent's coarse field
# at the end, and the cells a step reads within 1.3 more, over a bench InstNav episode.
BAND_SCALE = 1.2
BAND_MARGIN = 1.5


def geodesic(
    trav: np.ndarray,
    goal_rc: tuple[int, int],
    cell_size: float,
    speed: np.ndarray | None = None,
    band: float | None = None,
) -> np.ndarray:
    """[H, W] geodesic cost from the centre of `goal_rc` over `trav`; inf where unreachable.

    Args:
        trav: [H, W] bool cells one may cross.
        goal_rc: (row, col) source cell (made crossable if it is not).
        cell_size: metres.
        speed: [H, W] > 0 on `trav` (1 / cost per metre, `nav.motion.masks`); None = 1
            everywhere, so the cost is metres.
        band: stop the march past this cost (scikit-fmm's `narrow`): every cell costing less
            holds the whole march's value (FMM settles cells in increasing cost, each from
            cells settled before it), costlier ones may be inf. None: the whole grid.
    """
    narrow = 0.0 if band is None else max(float(band), 1e-9)
    trav = np.asarray(trav, dtype=bool)
    mask = ~trav
    mask[goal_rc] = False
    if not _has_free_side(mask, goal_rc):  # fenced in: nothing to march into
        out = np.full(trav.shape, np.inf)
        out[goal_rc] = 0.0
        return out
    from glmap_tools.nav._fmm_numba import travel_time_from  # numba loads on first use

    f = np.ones(trav.shape) if speed is None else np.where(mask | ~(speed > 0), 1.0, speed)
    source_speed = float(f[goal_rc])
    h, w = mask.shape
    out = travel_time_from(
        np.ascontiguousarray(mask), np.ascontiguousarray(f, dtype=np.float64), int(goal_rc[0]) % h,
        int(goal_rc[1]) % w, float(cell_size), narrow,
    )  # fmt: skip
    # The zero level set lies half a cell around the source centre; unsettled cells: inf.
    out += 0.5 * cell_size / source_speed
    out[goal_rc] = 0.0
    return out


def _has_free_side(mask: np.ndarray, rc: tuple[int, int]) -> bool:
    """Whether a 4-neighbour of `rc` is unmasked: FMM's axis stencils need one to start."""
    h, w = mask.shape
    r, c = rc
    sides = ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1))
    return any(0 <= i < h and 0 <= j < w and not mask[i, j] for i, j in sides)


def reference_geodesic(
    trav: np.ndarray,
    goal_rc: tuple[int, int],
    cell_size: float,
    speed: np.ndarray | None = None,
) -> np.ndarray:
    """Slow reference of `geodesic`: Dijkstra on the 8-connected grid (no corner cutting).

    Args and returns as `geodesic`; a step between two cells costs its length times the
    mean of their costs per metre (1 / speed), so lengths are those of 8-direction paths.
    """
    trav = np.asarray(trav, dtype=bool).copy()
    trav[goal_rc] = True
    h, w = trav.shape
    per_m = np.ones((h, w)) if speed is None else 1.0 / np.where(speed > 0, speed, 1.0)
    index = np.arange(h * w).reshape(h, w)
    src, dst, cost = [], [], []
    for dr, dc in _STEPS:
        r0, r1 = max(0, -dr), min(h, h - dr)
        c0, c1 = max(0, -dc), min(w, w - dc)
        a = trav[r0:r1, c0:c1]
        b = trav[r0 + dr : r1 + dr, c0 + dc : c1 + dc]
        ok = a & b
        if dr and dc:  # a diagonal step needs both side cells free
            ok &= trav[r0 + dr : r1 + dr, c0:c1] & trav[r0:r1, c0 + dc : c1 + dc]
        src.append(index[r0:r1, c0:c1][ok])
        dst.append(index[r0 + dr : r1 + dr, c0 + dc : c1 + dc][ok])
        mean = (per_m[r0:r1, c0:c1][ok] + per_m[r0 + dr : r1 + dr, c0 + dc : c1 + dc][ok]) / 2
        cost.append(mean * math.hypot(dr, dc) * cell_size)
    graph = sparse.csr_matrix(
        (np.concatenate(cost), (np.concatenate(src), np.concatenate(dst))), shape=(h * w, h * w)
    )
    dist = csgraph.dijkstra(graph, directed=True, indices=int(index[goal_rc]))
    return np.asarray(dist).reshape(h, w)


def descend(
    field: np.ndarray, start_rc: tuple[int, int], max_cells: int | None = None
) -> np.ndarray:
    """[K, 2] (row, col) cells from `start_rc` down `field` to its zero (steepest 8-neighbour).

    Stops at the source, at a local minimum, or after `max_cells` cells.
    """
    h, w = field.shape
    pad = np.full((h + 2, w + 2), np.inf)
    pad[1:-1, 1:-1] = field
    flat = pad.ravel()
    offsets = np.array([dr * (w + 2) + dc for dr, dc in _STEPS], dtype=np.int64)
    idx = (start_rc[0] + 1) * (w + 2) + start_rc[1] + 1
    out = [idx]
    limit = max_cells or h * w
    while flat[idx] > 0 and len(out) < limit:
        nbrs = idx + offsets
        k = int(np.argmin(flat[nbrs]))
        if not flat[nbrs[k]] < flat[idx]:
            break
        idx = int(nbrs[k])
        out.append(idx)
    cells = np.array(out, dtype=np.int64)
    return np.stack([cells // (w + 2) - 1, cells % (w + 2) - 1], axis=1)


@dataclass(frozen=True)
class DistanceField:
    """Geodesic metres from the agent, solved on cells `stride` map cells wide.

    Attributes:
        metres: [H, W] over the occupancy window (each map cell takes its block's value;
            inf where the map cell is not plannable or not reachable).
        coarse: [h, w] the FMM solution on the stride x stride blocks (= metres at stride 1).
        stride: map cells per planning cell.
        origin: (i0, j0) of the window.
        cell_size: metres per map cell.
    """

    metres: np.ndarray  # [H, W]
    coarse: np.ndarray  # [h, w]
    stride: int
    origin: tuple[int, int]
    cell_size: float


def _pool(values: np.ndarray, stride: int, op: np.ufunc) -> np.ndarray:
    """`op` over each stride x stride block (zero padded), as s * s strided slices: exact for
    max / or, and several times faster than a reduction over the axes of a 4-D view."""
    h, w = values.shape
    m = np.pad(values, ((0, -h % stride), (0, -w % stride)))
    out = m[::stride, ::stride].copy()
    for i in range(stride):
        for j in range(stride):
            if i or j:
                op(out, m[i::stride, j::stride], out=out)
    return out


def pool_any(mask: np.ndarray, stride: int) -> np.ndarray:
    """[ceil(H/s), ceil(W/s)] bool: blocks with at least one True cell."""
    return _pool(np.asarray(mask, dtype=bool), stride, np.logical_or)


def pool_max(values: np.ndarray, stride: int) -> np.ndarray:
    """[ceil(H/s), ceil(W/s)]: the largest value of each stride x stride block."""
    return _pool(np.asarray(values), stride, np.maximum)


def distance_field(
    occ: DenseOccupancy,
    ok: np.ndarray,
    source_rc: tuple[int, int],
    stride: int = 1,
    optimistic: bool = True,
    speed: np.ndarray | None = None,
) -> DistanceField:
    """FMM geodesic cost from `source_rc` over the plannable cells `ok` of `occ`.

    With stride > 1 the FMM runs on stride x stride blocks, a block plannable when any of
    its cells is (at the fastest of their speeds): when unknown cells are plannable
    (`optimistic`), the only blocked cells are inflated obstacles, at least 2 x agent radius
    thick, so no block joins the two sides of a wall, and a passage one agent wide stays
    open. Without optimism a thin line of unknown cells could be jumped, so the FMM then
    runs on map cells (stride 1). `speed` ([H, W], `nav.motion.masks`) weighs cells by
    their clearance cost; None: the cost is metres.
    """
    s = occ.cell_size
    if stride == 1 or not optimistic:
        coarse = geodesic(ok, source_rc, s, speed)
        return DistanceField(coarse, coarse, 1, occ.origin, s)
    blocks = pool_any(ok, stride)
    block_speed = None if speed is None else pool_max(np.where(ok, speed, 0.0), stride)
    coarse = geodesic(
        blocks, (source_rc[0] // stride, source_rc[1] // stride), s * stride, block_speed
    )
    h, w = ok.shape
    fine = np.repeat(np.repeat(coarse, stride, axis=0), stride, axis=1)[:h, :w]
    return DistanceField(np.where(ok, fine, np.inf), coarse, stride, occ.origin, s)


@dataclass(frozen=True)
class Plan:
    """A path to a goal and the next discrete action along it.

    Attributes:
        path: [K, 2] world (x, y) metres from the agent to the goal (cell centres).
        length: metres along `path`; inf when nothing can be reached.
        action: 'move_forward' | 'turn_left' | 'turn_right' | 'stop' ('stop' = arrived).
        reachable: whether the path ends at the goal (False: it ends at `goal_xy`'s nearest
            reachable point, see `goal_xy`).
        goal_xy: (x, y) the path ends at.
        boxed: no heading offers an open step (`nav.motion.drive`).
        back_off: the heading the path leaves by when the body cannot take it from here
            and the agent backs off (`Drive.wanted`, or toward the path one step on when no
            step lowers the cost-to-go); None otherwise.
        back_off_across: no step lowers the cost-to-go (`Drive.narrow`): the way is to be
            closed across, not at one cell.
    """

    path: np.ndarray  # [K, 2]
    length: float
    action: str
    reachable: bool
    goal_xy: tuple[float, float]
    boxed: bool = False
    back_off: float | None = None
    back_off_across: bool = False


def plan_on_field(
    occ: DenseOccupancy,
    field: DistanceField,
    agent_xy: tuple[float, float],
    heading: float,
    goal_xy: tuple[float, float],
    config: NavConfig,
    clear: np.ndarray | None = None,
    plannable: tuple[np.ndarray, np.ndarray] | None = None,
    arrive: float | None = None,
) -> Plan:
    """Plan with a distance `field` whose source is the agent; act on the cost-to-go.

    `field` says whether `goal_xy` can be reached (else the plan ends at its nearest
    reachable cell). The cost-to-go from that end is solved on map cells with the clearance
    cost, the path descends it from the agent, and `nav.motion.drive` picks the action.
    `clear` is `nav.motion.clearance(occ)` and `plannable` the (plannable, speed) of
    `nav.motion.masks` for the agent, when the caller has them already. The agent has
    arrived (action 'stop') within `arrive` metres of the end (default half a step).
    """
    goal_rc = occ.world_to_index(float(goal_xy[0]), float(goal_xy[1]))
    h, w = field.metres.shape
    inside = 0 <= goal_rc[0] < h and 0 <= goal_rc[1] < w
    reachable = inside and math.isfinite(float(field.metres[goal_rc]))
    goal = (float(goal_xy[0]), float(goal_xy[1]))
    end_rc: tuple[int, int] | None = goal_rc
    if not reachable:
        end_rc = nearest_finite(field.metres, goal_rc)
        if end_rc is None:
            return Plan(np.zeros((0, 2)), math.inf, "stop", False, goal)
    assert end_rc is not None
    end_xy = goal if reachable else occ.index_to_world(*end_rc)
    clear = clearance(occ) if clear is None else clear
    rc = agent_rc(occ, agent_xy)
    ok, speed = masks(occ, clear, rc, config)[1:] if plannable is None else plannable
    reach = math.ceil(config.forward_step / occ.cell_size) + 2  # cells `drive` reads around rc
    to_go = cost_to_go(ok, end_rc, rc, occ.cell_size, speed, float(field.metres[end_rc]), reach)
    if not math.isfinite(float(to_go[rc])):
        # Joined on the planning blocks only (a gap narrower than a block): follow them.
        to_go = distance_field(occ, ok, end_rc, field.stride, config.optimistic, speed).metres
    cells = descend(to_go, rc)
    path = np.array(
        [occ.index_to_world(int(r), int(c)) for r, c in cells], dtype=np.float64
    ).reshape(-1, 2)
    path[0] = agent_xy
    if len(path) > 1 and tuple(cells[-1]) == tuple(end_rc):
        path[-1] = end_xy
    else:
        path = np.vstack([path, np.array(end_xy)[None]])
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    if math.dist(agent_xy, end_xy) <= (config.forward_step / 2 if arrive is None else arrive):
        return Plan(path, length, "stop", reachable, end_xy)
    step = drive(occ, clear, to_go, agent_xy, heading, config)
    back_off = step.wanted
    if back_off is None and step.narrow:
        back_off = path_heading(path, agent_xy, config.forward_step)
    return Plan(
        path,
        length,
        step.action,
        reachable,
        end_xy,
        boxed=not step.open,
        back_off=back_off,
        back_off_across=step.narrow,
    )


def cost_to_go(
    ok: np.ndarray,
    end_rc: tuple[int, int],
    rc: tuple[int, int],
    cell_size: float,
    speed: np.ndarray | None,
    estimate: float,
    reach: int,
) -> np.ndarray:
    """`geodesic(ok, end_rc, cell_size, speed)` where the agent at `rc` reads it.

    The march stops at a band guessed from `estimate` (the agent's field at the end, which
    the cost at `rc` lies within a few per cent of): the cells the path descends through cost
    less than `rc`, so they lie inside it. When `rc` or a plannable cell within `reach` cells
    of it (the steps `nav.motion.drive` weighs) falls outside, the whole grid is solved, so
    every value the plan reads is the whole march's.
    """
    if math.isfinite(estimate):
        to_go = geodesic(ok, end_rc, cell_size, speed, BAND_SCALE * estimate + BAND_MARGIN)
        h, w = ok.shape
        r0, r1 = max(0, rc[0] - reach), min(h, rc[0] + reach + 1)
        c0, c1 = max(0, rc[1] - reach), min(w, rc[1] + reach + 1)
        around = to_go[r0:r1, c0:c1]
        if math.isfinite(float(to_go[rc])) and np.isfinite(around[ok[r0:r1, c0:c1]]).all():
            return to_go
    return geodesic(ok, end_rc, cell_size, speed)


def path_heading(path: np.ndarray, agent_xy: tuple[float, float], reach: float) -> float:
    """Radians from the agent toward the first point of `path` [K, 2] at least `reach`
    metres away (its last point when none is)."""
    far = np.flatnonzero(np.linalg.norm(path - np.asarray(agent_xy), axis=1) >= reach)
    x, y = path[int(far[0])] if len(far) else path[-1]
    return math.atan2(float(y) - agent_xy[1], float(x) - agent_xy[0])


def nearest_finite(field: np.ndarray, rc: tuple[int, int]) -> tuple[int, int] | None:
    """(row, col) of the finite cell of `field` closest (straight line) to `rc`, or None."""
    rows, cols = np.nonzero(np.isfinite(field))
    if len(rows) == 0:
        return None
    k = int(np.argmin((rows - rc[0]) ** 2 + (cols - rc[1]) ** 2))
    return (int(rows[k]), int(cols[k]))


def agent_field(
    occ: DenseOccupancy,
    agent_xy: tuple[float, float],
    config: NavConfig,
    clear: np.ndarray | None = None,
) -> DistanceField:
    """FMM geodesic cost from the agent over the plannable cells of `occ`."""
    rc = agent_rc(occ, agent_xy)
    clear = clearance(occ) if clear is None else clear
    _, ok, speed = masks(occ, clear, rc, config)
    return distance_field(occ, ok, rc, config.plan_stride, config.optimistic, speed)


def plan(
    occ: DenseOccupancy,
    agent_xy: tuple[float, float],
    agent_heading_rad: float,
    goal_xy: tuple[float, float],
    config: NavConfig | None = None,
    *,
    strict: bool = True,
) -> Plan:
    """Shortest path from the agent to `goal_xy` on the occupancy (clearance cost), and the
    next action.

    Args:
        occ: dense occupancy window holding the agent and the goal.
        agent_xy: (x, y) metres.
        agent_heading_rad: radians, counter-clockwise from +x.
        goal_xy: (x, y) metres.
        config: agent radius, step sizes, whether unknown cells may be crossed.
        strict: raise when the goal cannot be reached; else return a plan to the nearest
            reachable point with `reachable=False`.

    Raises:
        OutsideMapError: the agent or the goal lies outside the window.
        UnreachableGoalError: `strict` and no path leads to the goal (names the nearest
            reachable point).
    """
    config = config or NavConfig()
    agent_rc(occ, goal_xy, "goal")
    clear = clearance(occ)
    field = agent_field(occ, agent_xy, config, clear)
    out = plan_on_field(occ, field, agent_xy, agent_heading_rad, goal_xy, config, clear)
    if strict and not out.reachable:
        near = out.goal_xy if len(out.path) else None
        where = f"({near[0]:.2f}, {near[1]:.2f})" if near else "nowhere (the agent is boxed in)"
        raise UnreachableGoalError(
            f"goal ({goal_xy[0]:.2f}, {goal_xy[1]:.2f}) cannot be reached from the agent at "
            f"({agent_xy[0]:.2f}, {agent_xy[1]:.2f}): it is blocked or enclosed by obstacles "
            f"(the agent needs {config.agent_radius + occ.cell_size / 2:.3f} m of clearance). "
            f"Nearest reachable point: {where}.",
            (float(goal_xy[0]), float(goal_xy[1])),
            near,
        )
    return out
