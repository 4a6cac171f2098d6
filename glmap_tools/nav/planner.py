"""FMM geodesic distance (scikit-fmm), path by descent, and the next discrete action.

`geodesic` solves the eikonal equation |grad T| = 1 from a source cell over the plannable
cells (isotropic, second order). `reference_geodesic` is Dijkstra on the 8-connected grid
(scipy.sparse.csgraph): it can only move in 8 directions, so it overestimates a straight
line at angle a from an axis by (cos a + (sqrt 2 - 1) sin a), at most 8.24 % at 22.5 deg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import skfmm
from scipy import sparse
from scipy.sparse import csgraph

from glmap_tools.map.occupancy import OBSTACLE, DenseOccupancy
from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.errors import UnreachableGoalError
from glmap_tools.nav.grid import agent_rc, clear_footprint, plannable

# Dijkstra-8 / true length lies in [1, DIJKSTRA8_MAX_RATIO] for a straight, free path.
DIJKSTRA8_MAX_RATIO = math.cos(math.pi / 8) + (math.sqrt(2) - 1) * math.sin(math.pi / 8)
_STEPS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def geodesic(trav: np.ndarray, goal_rc: tuple[int, int], cell_size: float) -> np.ndarray:
    """[H, W] geodesic metres from the centre of `goal_rc` over `trav`; inf where unreachable.

    Args:
        trav: [H, W] bool cells one may cross.
        goal_rc: (row, col) source cell (made crossable if it is not).
        cell_size: metres.
    """
    trav = np.asarray(trav, dtype=bool)
    phi = np.ones(trav.shape)
    phi[goal_rc] = -1.0
    mask = ~trav
    mask[goal_rc] = False
    dist = skfmm.distance(np.ma.MaskedArray(phi, mask), dx=cell_size)
    # The zero level set lies half a cell around the source centre.
    out = np.ma.filled(dist, np.inf).astype(np.float64) + 0.5 * cell_size
    out[goal_rc] = 0.0
    return out


def reference_geodesic(trav: np.ndarray, goal_rc: tuple[int, int], cell_size: float) -> np.ndarray:
    """Slow reference of `geodesic`: Dijkstra on the 8-connected grid (no corner cutting).

    Args and returns as `geodesic`; lengths are those of 8-direction grid paths.
    """
    trav = np.asarray(trav, dtype=bool).copy()
    trav[goal_rc] = True
    h, w = trav.shape
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
        cost.append(np.full(int(ok.sum()), math.hypot(dr, dc) * cell_size))
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
    r, c = start_rc
    cells = [(r, c)]
    limit = max_cells or h * w
    while field[r, c] > 0 and len(cells) < limit:
        best, best_v = (r, c), field[r, c]
        for dr, dc in _STEPS:
            rr, cc = r + dr, c + dc
            if 0 <= rr < h and 0 <= cc < w:
                # Normalise by step length so diagonals are compared fairly.
                v = field[rr, cc]
                if v < best_v:
                    best, best_v = (rr, cc), v
        if best == (r, c):
            break
        r, c = best
        cells.append((r, c))
    return np.array(cells, dtype=np.int64)


@dataclass(frozen=True)
class Plan:
    """A path to a goal and the next discrete action along it.

    Attributes:
        path: [K, 2] world (x, y) metres from the agent to the goal (cell centres).
        length: geodesic metres from the agent to the goal (FMM); inf when unreachable.
        action: 'move_forward' | 'turn_left' | 'turn_right' | 'stop' ('stop' = arrived).
        reachable: whether the path ends at the goal (False: it ends at `goal_xy`'s nearest
            reachable point, see `goal_xy`).
        goal_xy: (x, y) the path ends at.
    """

    path: np.ndarray  # [K, 2]
    length: float
    action: str
    reachable: bool
    goal_xy: tuple[float, float]


def next_action(
    path: np.ndarray,
    agent_xy: tuple[float, float],
    heading: float,
    config: NavConfig,
    arrived: bool,
    blocked_ahead: bool = False,
) -> str:
    """The discrete action that follows `path` ([K, 2] world xy from the agent).

    'stop' when `arrived`; otherwise turn toward the path point `config.lookahead` metres
    ahead until the heading is within half a turn of it, then move forward, unless
    `blocked_ahead` (a forward step would enter blocked space): then turn toward the path.
    """
    if arrived or len(path) == 0:
        return "stop"
    d = np.hypot(path[:, 0] - agent_xy[0], path[:, 1] - agent_xy[1])
    ahead = np.flatnonzero(d >= config.lookahead)
    target = path[ahead[0]] if len(ahead) else path[-1]
    if math.hypot(target[0] - agent_xy[0], target[1] - agent_xy[1]) < 1e-6:
        return "stop"
    want = math.atan2(target[1] - agent_xy[1], target[0] - agent_xy[0])
    diff = (want - heading + math.pi) % (2 * math.pi) - math.pi
    if abs(diff) <= config.turn_angle / 2 + 1e-9 and not blocked_ahead:
        return "move_forward"
    return "turn_left" if diff >= 0 else "turn_right"


def plan_on_field(
    occ: DenseOccupancy,
    field: np.ndarray,
    agent_xy: tuple[float, float],
    heading: float,
    goal_xy: tuple[float, float],
    config: NavConfig,
) -> Plan:
    """Plan from a geodesic `field` whose source is the agent: descend from the goal to it."""
    s = occ.cell_size
    goal_rc = occ.world_to_index(float(goal_xy[0]), float(goal_xy[1]))
    h, w = field.shape
    inside = 0 <= goal_rc[0] < h and 0 <= goal_rc[1] < w
    length = float(field[goal_rc]) if inside else math.inf
    reachable = math.isfinite(length)
    goal = (float(goal_xy[0]), float(goal_xy[1]))
    end_rc: tuple[int, int] | None = goal_rc
    if not reachable:
        end_rc = nearest_finite(field, goal_rc)
        if end_rc is None:
            return Plan(np.zeros((0, 2)), math.inf, "stop", False, goal)
        length = float(field[end_rc])
    assert end_rc is not None
    cells = descend(field, end_rc)[::-1]
    path = np.stack(
        [(cells[:, 1] + occ.origin[0] + 0.5) * s, (cells[:, 0] + occ.origin[1] + 0.5) * s], 1
    )
    path[0] = agent_xy
    end_xy = goal if reachable else (float(path[-1, 0]), float(path[-1, 1]))
    if reachable:
        path[-1] = goal_xy
    arrived = length <= config.forward_step / 2
    action = next_action(
        path,
        agent_xy,
        heading,
        config,
        arrived,
        not forward_is_free(occ, field, agent_xy, heading, config),
    )
    return Plan(path, length, action, reachable, end_xy)


def forward_is_free(
    occ: DenseOccupancy,
    field: np.ndarray,
    agent_xy: tuple[float, float],
    heading: float,
    config: NavConfig,
) -> bool:
    """Whether one forward step stays off obstacle cells (seen, or where a move was stopped).

    Only hard evidence counts: the inflated margin is for planning, and an agent that ended
    up inside it (noise, a cleared footprint) must still be able to move out.
    """
    h, w = field.shape
    n = max(1, math.ceil(config.forward_step / (occ.cell_size / 2)))
    for k in range(1, n + 1):
        t = config.forward_step * k / n
        r, c = occ.world_to_index(
            agent_xy[0] + t * math.cos(heading), agent_xy[1] + t * math.sin(heading)
        )
        if 0 <= r < h and 0 <= c < w and occ.state[r, c] == OBSTACLE:
            return False
    return True


def nearest_finite(field: np.ndarray, rc: tuple[int, int]) -> tuple[int, int] | None:
    """(row, col) of the finite cell of `field` closest (straight line) to `rc`, or None."""
    rows, cols = np.nonzero(np.isfinite(field))
    if len(rows) == 0:
        return None
    k = int(np.argmin((rows - rc[0]) ** 2 + (cols - rc[1]) ** 2))
    return (int(rows[k]), int(cols[k]))


def agent_field(
    occ: DenseOccupancy, agent_xy: tuple[float, float], config: NavConfig
) -> np.ndarray:
    """[H, W] FMM geodesic metres from the agent over the plannable cells of `occ`."""
    rc = agent_rc(occ, agent_xy)
    ok = plannable(occ, config.agent_radius, config.optimistic)
    ok = clear_footprint(ok, rc, config.agent_radius / occ.cell_size)
    return geodesic(ok, rc, occ.cell_size)


def plan(
    occ: DenseOccupancy,
    agent_xy: tuple[float, float],
    agent_heading_rad: float,
    goal_xy: tuple[float, float],
    config: NavConfig | None = None,
    *,
    strict: bool = True,
) -> Plan:
    """Shortest path from the agent to `goal_xy` on the inflated occupancy, and the next action.

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
    field = agent_field(occ, agent_xy, config)
    out = plan_on_field(occ, field, agent_xy, agent_heading_rad, goal_xy, config)
    if strict and not out.reachable:
        near = out.goal_xy if len(out.path) else None
        where = f"({near[0]:.2f}, {near[1]:.2f})" if near else "nowhere (the agent is boxed in)"
        raise UnreachableGoalError(
            f"goal ({goal_xy[0]:.2f}, {goal_xy[1]:.2f}) cannot be reached from the agent at "
            f"({agent_xy[0]:.2f}, {agent_xy[1]:.2f}): it is blocked or enclosed by obstacles "
            f"(inflated by the agent radius {config.agent_radius} m). Nearest reachable "
            f"point: {where}.",
            (float(goal_xy[0]), float(goal_xy[1])),
            near,
        )
    return out
