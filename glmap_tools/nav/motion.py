"""Motion: the clearance cost, the cost-to-go controller and bump marks.

One layer for every policy and for `navigate_to` (nav/design.md "Motion"):

- **clearance**: metres from each cell centre to the nearest obstacle cell centre. The
  simulator lets the agent's centre stand where the nearest blocked cell's centre is at least
  `agent_radius + cell/2` away, so the map blocks cells below that **body radius**.
- **cost**: crossing a cell costs `1 + k ((c_pref - c) / (c_pref - r_body))^2` per metre when
  its clearance c is below `NavConfig.clearance` (c_pref; k = `clearance_cost`), else 1. Paths
  take the middle of a doorway and keep off furniture where there is room.
- **controller** (`drive`): with T the cost-to-go to the waypoint, each of the 12 headings
  one turn apart has a landing point one forward step away; a heading is open when every
  point of that step keeps a clearance of at least min(safe radius, the clearance where the
  agent stands less half a cell): it never goes nearer an obstacle than the safe radius, or
  than it already is. The agent moves forward when the heading it faces is the best open one
  by T(landing) + `turn_cost` per turn, else it turns toward the best one. Turning changes
  neither T nor which headings are open, so a turn in place ends within 6 turns unless a new
  frame changes the map.
- **bump marks** (`bump_cells`): a forward move the simulator stopped short leaves the cell
  where the body touched as an obstacle for the rest of the episode; when the map shows no
  obstacle near it (furniture below the camera's view) a 0.6 m segment across the heading is
  marked, so one bump outlines the unseen edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, DenseOccupancy
from glmap_tools.nav.config import NavConfig
from glmap_tools.nav.grid import clear_footprint, distance_to_zero

EXPLAINED_CELLS = 2  # a map obstacle this close to the contact point explains a bump
UNSEEN_EDGE = 0.3  # metres each side of the contact an unexplained bump marks


def body_radius(config: NavConfig, cell_size: float) -> float:
    """Metres: the clearance the simulator asks of a cell centre (agent radius + half a cell)."""
    return config.agent_radius + cell_size / 2


def safe_radius(config: NavConfig, cell_size: float) -> float:
    """Metres of clearance a forward step keeps when it can (body radius + safety margin)."""
    return body_radius(config, cell_size) + config.safety_margin


def clearance(occ: DenseOccupancy) -> np.ndarray:
    """[H, W] metres from each cell centre to the nearest obstacle cell centre (inf: none)."""
    obstacle = occ.state == OBSTACLE
    if not obstacle.any():
        return np.full(occ.state.shape, np.inf)
    return distance_to_zero(~obstacle) * occ.cell_size


def cell_cost(clear: np.ndarray, config: NavConfig, cell_size: float) -> np.ndarray:
    """[H, W] cost per metre of crossing each cell (>= 1; inf below the body radius)."""
    r = body_radius(config, cell_size)
    span = max(config.clearance - r, 1e-9)
    frac = np.clip((config.clearance - clear) / span, 0.0, 1.0)
    cost = 1.0 + config.clearance_cost * frac**2
    return np.where(clear < r - 1e-9, np.inf, cost)


def bilinear(field: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """[K] values of `field` at fractional (row, col) cell coordinates [K, 2] (cell centres
    at integers); a point next to an inf or outside cell takes its nearest cell's value."""
    h, w = field.shape
    r, c = rc[:, 0], rc[:, 1]
    r0, c0 = np.floor(r).astype(np.int64), np.floor(c).astype(np.int64)
    fr, fc = r - r0, c - c0
    out = np.full(len(rc), np.inf)
    near_r = np.clip(np.rint(r).astype(np.int64), 0, h - 1)
    near_c = np.clip(np.rint(c).astype(np.int64), 0, w - 1)
    inside = (np.rint(r) >= 0) & (np.rint(r) < h) & (np.rint(c) >= 0) & (np.rint(c) < w)
    out[inside] = field[near_r[inside], near_c[inside]]
    ok = (r0 >= 0) & (r0 + 1 < h) & (c0 >= 0) & (c0 + 1 < w)
    if ok.any():
        a, b = r0[ok], c0[ok]
        v = np.stack([field[a, b], field[a, b + 1], field[a + 1, b], field[a + 1, b + 1]])
        finite = np.isfinite(v).all(axis=0)
        x, y = fc[ok], fr[ok]
        with np.errstate(invalid="ignore"):
            lerp = (v[0] * (1 - x) + v[1] * x) * (1 - y) + (v[2] * (1 - x) + v[3] * x) * y
        idx = np.flatnonzero(ok)[finite]
        out[idx] = lerp[finite]
    return out


def step_points(
    agent_xy: tuple[float, float], headings: np.ndarray, config: NavConfig, cell_size: float
) -> np.ndarray:
    """[K, n, 2] world points along one forward step on each heading, a quarter cell apart."""
    n = max(1, math.ceil(config.forward_step / (cell_size / 4)))
    t = config.forward_step * np.arange(1, n + 1) / n
    dx, dy = np.cos(headings)[:, None], np.sin(headings)[:, None]
    return np.stack([agent_xy[0] + t * dx, agent_xy[1] + t * dy], axis=2)


def _rc_float(occ: DenseOccupancy, xy: np.ndarray) -> np.ndarray:
    """[..., 2] fractional (row, col) of world points (cell centres at integers)."""
    s = occ.cell_size
    return np.stack(
        [xy[..., 1] / s - occ.origin[1] - 0.5, xy[..., 0] / s - occ.origin[0] - 0.5], axis=-1
    )


def clearance_along(occ: DenseOccupancy, clear: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """[...] clearance of the cells holding the world points [..., 2] (inf outside)."""
    s = occ.cell_size
    r = np.floor(xy[..., 1] / s).astype(np.int64) - occ.origin[1]
    c = np.floor(xy[..., 0] / s).astype(np.int64) - occ.origin[0]
    h, w = clear.shape
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    out = np.full(r.shape, np.inf)
    out[inside] = clear[r[inside], c[inside]]
    return out


def steps_open(
    occ: DenseOccupancy,
    clear: np.ndarray,
    agent_xy: tuple[float, float],
    headings: np.ndarray,
    config: NavConfig,
    radius: float | None = None,
) -> np.ndarray:
    """[K] bool: whether one forward step on each heading is open: every point of it keeps
    a clearance of min(`radius`, the clearance where the agent stands less half a cell).
    `radius` defaults to the safe radius; the body radius is what the simulator asks."""
    s = occ.cell_size
    radius = safe_radius(config, s) if radius is None else radius
    pts = step_points(agent_xy, np.asarray(headings, dtype=np.float64), config, s)
    here = float(clearance_along(occ, clear, np.array([agent_xy]))[0])
    need = min(radius, here - s / 2)
    return np.asarray((clearance_along(occ, clear, pts) >= need - 1e-9).all(axis=1))


@dataclass(frozen=True)
class Drive:
    """What `drive` chose.

    Attributes:
        action: 'move_forward' | 'turn_left' | 'turn_right'.
        turns: signed turns to the chosen heading (+ = left; 0 = the heading faced).
        open: whether the chosen heading's step is open (False: no heading is; boxed in).
        gain: T where the agent stands less T where the chosen step lands (> 0: progress).
        wanted: when the agent backs off (no step the body fits makes progress), the
            heading of the step that would make the most progress: the way the plan goes
            that the body cannot take from here; None otherwise.
        narrow: the agent backs off and no step at all lowers the cost-to-go: the plan's
            way from here is narrower or bends sooner than one step (house-tune s02-004).
    """

    action: str
    turns: int
    open: bool
    gain: float
    wanted: float | None = None
    narrow: bool = False


def drive(
    occ: DenseOccupancy,
    clear: np.ndarray,
    to_go: np.ndarray,
    agent_xy: tuple[float, float],
    heading: float,
    config: NavConfig,
) -> Drive:
    """The next discrete action toward the source of the cost-to-go `to_go` (module doc).

    Args:
        occ: the occupancy window `clear` and `to_go` are over.
        clear: [H, W] clearance metres (`clearance`, bump marks included).
        to_go: [H, W] cost-to-go to the waypoint (inf where it cannot be reached).
        agent_xy: (x, y) metres.
        heading: radians.
        config: step, turn, radii, turn cost.
    """
    s = occ.cell_size
    n_turns = round(360 / config.turn_angle_deg)
    ks = np.arange(-(n_turns // 2) + 1, n_turns // 2 + 1)  # -5..6 for 30 deg turns
    headings = heading + ks * config.turn_angle
    pts = step_points(agent_xy, headings, config, s)
    t0 = float(bilinear(to_go, _rc_float(occ, np.array([agent_xy])))[0])
    landing = bilinear(to_go, _rc_float(occ, pts[:, -1]))
    cost = landing + config.turn_cost * np.abs(ks)
    safe = steps_open(occ, clear, agent_xy, headings, config) & np.isfinite(landing)
    body = steps_open(occ, clear, agent_xy, headings, config, body_radius(config, s))
    body &= np.isfinite(landing)
    better = landing < t0 - 1e-9 if math.isfinite(t0) else np.isfinite(landing)
    # Safe steps that make progress; else steps the body fits that do (a tight doorway);
    # else the least bad step the body fits (back off); else nothing is open.
    tiers = (safe & better, body & better, body)
    tier = next((t for t, usable in enumerate(tiers) if usable.any()), None)
    if tier is None:
        return Drive("turn_left", 1, False, 0.0)
    usable = tiers[tier]
    k = int(np.flatnonzero(usable)[np.argmin(cost[usable])])
    turns = int(ks[k])
    gain = t0 - float(landing[k]) if math.isfinite(t0) else 0.0
    wanted = None
    if tier == 2 and better.any():
        wanted = float(headings[int(np.flatnonzero(better)[np.argmin(cost[better])])])
    narrow = tier == 2 and not better.any()
    if turns == 0:
        return Drive("move_forward", 0, True, gain, wanted, narrow)
    return Drive("turn_left" if turns > 0 else "turn_right", turns, True, gain, wanted, narrow)


def bump_cells(
    occ: DenseOccupancy,
    stop_xy: tuple[float, float],
    heading: float,
    config: NavConfig,
    across: bool = False,
) -> list[tuple[int, int]]:
    """(i, j) cells to mark as obstacles after a forward move stopped at `stop_xy`.

    The contact point is taken one body radius straight ahead, on the line `drive` checks.
    With a map obstacle within `EXPLAINED_CELLS` of it (a door jamb the path came too near)
    that one cell is marked; with none (something the camera did not see: furniture below
    its view), a segment across the heading `UNSEEN_EDGE` to each side (0.18 m, the body,
    left 2 of 24 table passes at 2 bumps and one at 4; 0.3 m at most 2, tests/test_nav_motion).
    `across`: the segment in every case (a way too narrow for the agent's steps, to close).
    """
    s = occ.cell_size
    contact = contact_point(stop_xy, heading, config, s)
    r, c = occ.world_to_index(float(contact[0]), float(contact[1]))
    h, w = occ.state.shape
    k = EXPLAINED_CELLS
    near = occ.state[max(0, r - k) : max(0, r + k + 1), max(0, c - k) : max(0, c + k + 1)]
    explained = 0 <= r < h and 0 <= c < w and bool((near == OBSTACLE).any())
    cell = (math.floor(contact[0] / s), math.floor(contact[1] / s))
    if explained and not across:
        return [cell]
    side = np.array([-math.sin(heading), math.cos(heading)])
    n = math.ceil(UNSEEN_EDGE / (s / 2))
    offs = np.linspace(-UNSEEN_EDGE, UNSEEN_EDGE, 2 * n + 1)
    seg = contact[None, :] + offs[:, None] * side[None, :]
    cells = {(math.floor(x / s), math.floor(y / s)) for x, y in seg}
    cells.add(cell)
    return sorted(cells)


def contact_point(
    stop_xy: tuple[float, float], heading: float, config: NavConfig, cell_size: float
) -> np.ndarray:
    """[2] where a forward move stopped at `stop_xy` touched: one body radius straight
    ahead, on the line `drive` checks."""
    pts = step_points(stop_xy, np.array([heading]), config, cell_size)[0]
    t = np.linalg.norm(pts - np.array(stop_xy), axis=1)
    return pts[int(np.argmin(np.abs(t - body_radius(config, cell_size))))]


def contact_cell(
    stop_xy: tuple[float, float], heading: float, config: NavConfig, cell_size: float
) -> tuple[int, int]:
    """The (i, j) cell of `contact_point`: the narrowest bump mark."""
    x, y = contact_point(stop_xy, heading, config, cell_size)
    return (math.floor(float(x) / cell_size), math.floor(float(y) / cell_size))


def marks_near(
    marks: set[tuple[int, int]], xy: tuple[float, float], cell_size: float, radius: float
) -> set[tuple[int, int]]:
    """The (i, j) bump marks whose cell centre is within `radius` m of `xy`."""
    return {
        c
        for c in marks
        if math.dist(((c[0] + 0.5) * cell_size, (c[1] + 0.5) * cell_size), xy) <= radius
    }


def forget_marks_near(
    marks: set[tuple[int, int]], xy: tuple[float, float], cell_size: float, radius: float
) -> bool:
    """Drop the (i, j) bump marks whose cell centre is within `radius` m of `xy` (in place);
    True when any were dropped."""
    near = marks_near(marks, xy, cell_size, radius)
    marks -= near
    return bool(near)


def footprint(shape: tuple[int, int], rc: tuple[int, int], radius_cells: float) -> np.ndarray:
    """[H, W] bool: the cells under a disk of `radius_cells` around (row, col) `rc`."""
    return clear_footprint(np.zeros(shape, dtype=bool), rc, radius_cells)


def masks(
    occ: DenseOccupancy, clear: np.ndarray, rc: tuple[int, int], config: NavConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(traversable, plannable, speed) [H, W] over `occ` for an agent at (row, col) `rc`.

    Traversable: seen-free cells with clearance >= the body radius; plannable: those plus
    unknown ones when `config.optimistic`; speed: 1 / `cell_cost` on plannable cells, 0 else.
    The cells under the agent's footprint are both (it stands there) and cost the most, so
    a plan from inside an obstacle's margin leaves it by the shortest way.
    """

    s = occ.cell_size
    cost = cell_cost(clear, config, s)
    open_ = np.isfinite(cost)
    free = occ.state == FREE
    ok = (free | (occ.state == UNKNOWN)) if config.optimistic else free
    foot = footprint(occ.state.shape, rc, config.agent_radius / s)
    trav = (free & open_) | foot
    ok = (ok & open_) | foot
    worst = 2.0 * (1.0 + config.clearance_cost)
    speed = np.where(ok, 1.0 / np.where(open_, cost, worst), 0.0)
    return trav, ok, speed
