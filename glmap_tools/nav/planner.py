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
    mask = ~trav
    mask[goal_rc] = False
    if mask.sum() == mask.size - 1:  # nothing around the source to march into
        out = np.full(trav.shape, np.inf)
        out[goal_rc] = 0.0
        return out
    phi = np.ones(trav.shape)
    phi[goal_rc] = -1.0
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

    def block_of(self, rc: tuple[int, int]) -> tuple[int, int]:
        return (rc[0] // self.stride, rc[1] // self.stride)

    def block_xy(self, blocks: np.ndarray) -> np.ndarray:
        """[K, 2] world (x, y) of the centres of [K, 2] (row, col) planning blocks."""
        half = self.stride / 2.0
        return np.stack(
            [
                (blocks[:, 1] * self.stride + half + self.origin[0]) * self.cell_size,
                (blocks[:, 0] * self.stride + half + self.origin[1]) * self.cell_size,
            ],
            axis=1,
        )


def pool_any(mask: np.ndarray, stride: int) -> np.ndarray:
    """[ceil(H/s), ceil(W/s)] bool: blocks with at least one True cell."""
    h, w = mask.shape
    ph, pw = -h % stride, -w % stride
    m = np.pad(mask, ((0, ph), (0, pw)))
    blocks = m.reshape(m.shape[0] // stride, stride, m.shape[1] // stride, stride)
    return np.asarray(blocks.any(axis=(1, 3)))


def distance_field(
    occ: DenseOccupancy,
    ok: np.ndarray,
    source_rc: tuple[int, int],
    stride: int = 1,
    optimistic: bool = True,
) -> DistanceField:
    """FMM geodesic metres from `source_rc` over the plannable cells `ok` of `occ`.

    With stride > 1 the FMM runs on stride x stride blocks, a block plannable when any of
    its cells is: when unknown cells are plannable (`optimistic`), the only blocked cells
    are inflated obstacles, at least 2 x agent radius thick, so no block joins the two
    sides of a wall, and a passage one agent wide stays open. Without optimism a thin line
    of unknown cells could be jumped, so the FMM then runs on map cells (stride 1).
    """
    s = occ.cell_size
    if stride == 1 or not optimistic:
        coarse = geodesic(ok, source_rc, s)
        return DistanceField(coarse, coarse, 1, occ.origin, s)
    blocks = pool_any(ok, stride)
    coarse = geodesic(blocks, (source_rc[0] // stride, source_rc[1] // stride), s * stride)
    h, w = ok.shape
    fine = np.repeat(np.repeat(coarse, stride, axis=0), stride, axis=1)[:h, :w]
    return DistanceField(np.where(ok, fine, np.inf), coarse, stride, occ.origin, s)


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


def heading_error(
    path: np.ndarray, agent_xy: tuple[float, float], heading: float, lookahead: float
) -> float | None:
    """Radians to turn (counter-clockwise +) to face the path point `lookahead` m away."""
    d = np.hypot(path[:, 0] - agent_xy[0], path[:, 1] - agent_xy[1])
    ahead = np.flatnonzero(d >= lookahead)
    target = path[ahead[0]] if len(ahead) else path[-1]
    if math.hypot(target[0] - agent_xy[0], target[1] - agent_xy[1]) < 1e-6:
        return None
    want = math.atan2(target[1] - agent_xy[1], target[0] - agent_xy[0])
    return (want - heading + math.pi) % (2 * math.pi) - math.pi


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
    diff = heading_error(path, agent_xy, heading, config.lookahead)
    if diff is None:
        return "stop"
    if abs(diff) <= config.turn_angle / 2 + 1e-9 and not blocked_ahead:
        return "move_forward"
    return "turn_left" if diff >= 0 else "turn_right"


def plan_on_field(
    occ: DenseOccupancy,
    field: DistanceField,
    agent_xy: tuple[float, float],
    heading: float,
    goal_xy: tuple[float, float],
    config: NavConfig,
) -> Plan:
    """Plan with a distance `field` whose source is the agent: descend from the goal to it."""
    goal_rc = occ.world_to_index(float(goal_xy[0]), float(goal_xy[1]))
    h, w = field.metres.shape
    inside = 0 <= goal_rc[0] < h and 0 <= goal_rc[1] < w
    length = float(field.metres[goal_rc]) if inside else math.inf
    reachable = math.isfinite(length)
    goal = (float(goal_xy[0]), float(goal_xy[1]))
    end_rc: tuple[int, int] | None = goal_rc
    if not reachable:
        end_rc = nearest_finite(field.metres, goal_rc)
        if end_rc is None:
            return Plan(np.zeros((0, 2)), math.inf, "stop", False, goal)
        length = float(field.metres[end_rc])
    assert end_rc is not None
    blocks = descend(field.coarse, field.block_of(end_rc))[::-1]
    path = field.block_xy(blocks)
    path[0] = agent_xy
    end_xy = goal if reachable else occ.index_to_world(*end_rc)
    path[-1] = end_xy
    arrived = length <= config.forward_step / 2
    blocked = not forward_is_free(occ, agent_xy, heading, config)
    action = next_action(path, agent_xy, heading, config, arrived, blocked)
    if action in ("turn_left", "turn_right") and not blocked:
        # The path leaves between this heading and the next turn, and that turn faces a
        # blocked step: go on this way (the plan is redone every step).
        diff = heading_error(path, agent_xy, heading, config.lookahead)
        turned = heading + (config.turn_angle if action == "turn_left" else -config.turn_angle)
        if (
            diff is not None
            and abs(diff) <= config.turn_angle
            and not forward_is_free(occ, agent_xy, turned, config)
        ):
            action = "move_forward"
    return Plan(path, length, action, reachable, end_xy)


def forward_points(
    agent_xy: tuple[float, float], heading: float, config: NavConfig, cell_size: float
) -> tuple[np.ndarray, np.ndarray]:
    """Points along one forward step, a quarter cell apart: ([n, 2] world xy, [n] metres).

    `forward_is_free` checks the cells of these points and a stopped move marks the cell
    of one of them, so the mark always lies on the line the check looks along.
    """
    n = max(1, math.ceil(config.forward_step / (cell_size / 4)))
    t = config.forward_step * np.arange(1, n + 1) / n
    xy = np.stack(
        [agent_xy[0] + t * math.cos(heading), agent_xy[1] + t * math.sin(heading)], axis=1
    )
    return xy, t


def forward_is_free(
    occ: DenseOccupancy,
    agent_xy: tuple[float, float],
    heading: float,
    config: NavConfig,
) -> bool:
    """Whether one forward step stays off obstacle cells (seen, or where a move was stopped).

    Only hard evidence counts: the inflated margin is for planning, and an agent that ended
    up inside it (noise, a cleared footprint) must still be able to move out.
    """
    xy, _ = forward_points(agent_xy, heading, config, occ.cell_size)
    r = np.floor(xy[:, 1] / occ.cell_size).astype(np.int64) - occ.origin[1]
    c = np.floor(xy[:, 0] / occ.cell_size).astype(np.int64) - occ.origin[0]
    h, w = occ.state.shape
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    return not bool((occ.state[r[inside], c[inside]] == OBSTACLE).any())


def nearest_finite(field: np.ndarray, rc: tuple[int, int]) -> tuple[int, int] | None:
    """(row, col) of the finite cell of `field` closest (straight line) to `rc`, or None."""
    rows, cols = np.nonzero(np.isfinite(field))
    if len(rows) == 0:
        return None
    k = int(np.argmin((rows - rc[0]) ** 2 + (cols - rc[1]) ** 2))
    return (int(rows[k]), int(cols[k]))


def agent_field(
    occ: DenseOccupancy, agent_xy: tuple[float, float], config: NavConfig
) -> DistanceField:
    """FMM geodesic metres from the agent over the plannable cells of `occ`."""
    rc = agent_rc(occ, agent_xy)
    ok = plannable(occ, config.agent_radius, config.optimistic)
    ok = clear_footprint(ok, rc, config.agent_radius / occ.cell_size)
    return distance_field(occ, ok, rc, config.plan_stride, config.optimistic)


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
