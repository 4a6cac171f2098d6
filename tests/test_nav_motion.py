"""The motion layer against the simulator's own body model (sim.motion on a NavGrid).

The map handed to the planner is the simulator's free space (a perfect map), or that map
without an obstacle the camera would not see; every step is one `plan` (as `navigate_to`
takes it) and one simulator action, and a stopped move marks `bump_cells`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from glmap_tools.map.occupancy import FREE, OBSTACLE, DenseOccupancy
from glmap_tools.nav import NavConfig, bump_cells, plan
from glmap_tools.sim.motion import Action, AgentState, MotionConfig, apply_action
from glmap_tools.sim.navgrid import NavGrid

CELL = 0.05
CONFIG = NavConfig()
ACTION = {"move_forward": Action.MOVE_FORWARD, "turn_left": Action.TURN_LEFT}
ACTION["turn_right"] = Action.TURN_RIGHT


def grid_of(free: np.ndarray) -> NavGrid:
    """The simulator's rule: a centre is navigable when the nearest blocked cell's edge is
    at least the agent radius away (sim.navgrid.build_nav_grid)."""
    clearance = ndimage.distance_transform_edt(free) * CELL
    navigable = clearance - CELL / 2 >= CONFIG.agent_radius - 1e-9
    return NavGrid(np.zeros(2), CELL, free, navigable, CONFIG.agent_radius)


def box(free: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> None:
    """Block the cells whose centres lie in [x0, x1] x [y0, y1] metres."""
    xs = (np.arange(free.shape[1]) + 0.5) * CELL
    ys = (np.arange(free.shape[0]) + 0.5) * CELL
    free[np.ix_((ys >= y0) & (ys <= y1), (xs >= x0) & (xs <= x1))] = False


def flat(door: float | None, middle: float = 2.025) -> np.ndarray:
    """[80, 120] free cells of a 6 m x 4 m flat; with `door`, a 0.1 m wall at x = 3 m with a
    doorway of that width centred at y = `middle` (a cell centre)."""
    free = np.ones((80, 120), dtype=bool)
    free[0, :] = free[-1, :] = free[:, 0] = free[:, -1] = False
    if door is not None:
        box(free, 2.95, 0.0, 3.05, middle - door / 2 - 1e-6)
        box(free, 2.95, middle + door / 2 + 1e-6, 3.05, 4.0)
    return free


def walk(
    sim_free: np.ndarray,
    map_free: np.ndarray,
    start: AgentState,
    goal: tuple[float, float],
    max_steps: int = 150,
    mark_back_off: bool = True,
) -> tuple[bool, int, int, int]:
    """(reached, collisions, longest run of turns in place, back-offs) of one walk to
    `goal`; a plan that backs off marks the step it could not take, as `nav.decide` does."""
    grid = grid_of(sim_free)
    base = np.where(map_free, FREE, OBSTACLE).astype(np.int8)
    marks: set[tuple[int, int]] = set()
    state, collisions, run, longest, backs = start, 0, 0, 0, 0
    for _ in range(max_steps):
        occ_state = base.copy()
        for i, j in marks:
            occ_state[j, i] = OBSTACLE
        occ = DenseOccupancy(occ_state, (0, 0), CELL)
        out = plan(occ, (state.x, state.y), state.heading, goal, CONFIG, strict=False)
        if out.action == "stop":
            return True, collisions, longest, backs
        backs += out.back_off is not None
        if mark_back_off and out.back_off is not None:
            across = out.back_off_across
            marks.update(bump_cells(occ, (state.x, state.y), out.back_off, CONFIG, across=across))
        run = run + 1 if out.action != "move_forward" else 0
        longest = max(longest, run)
        state, collided = apply_action(grid, state, ACTION[out.action], MotionConfig())
        if collided:
            collisions += 1
            bare = DenseOccupancy(base, (0, 0), CELL)
            marks.update(bump_cells(bare, (state.x, state.y), state.heading, CONFIG))
    return False, collisions, longest, backs


def starts(free: np.ndarray, n: int, seed: int, x_max: float) -> list[AgentState]:
    """`n` navigable poses with x < `x_max` and random headings (not aligned with the walls)."""
    grid = grid_of(free)
    rng = np.random.default_rng(seed)
    out: list[AgentState] = []
    while len(out) < n:
        x, y = rng.uniform(0.3, x_max), rng.uniform(0.3, 3.7)
        if grid.navigable_at(x, y):
            out.append(AgentState(float(x), float(y), float(rng.uniform(-math.pi, math.pi))))
    return out


def test_the_narrowest_doorway_of_the_benchmark_is_crossed_without_a_collision() -> None:
    """A 0.56 m doorway: the body (0.36 m) plus the simulator's half cell each side is
    0.41 m, so 3 cells of centre positions are left, the narrowest passage a benchmark
    episode may need (sim.navgrid.MIN_PASSAGE_CELLS). From 20 starts in the left room,
    with headings off the walls' axes, the agent reaches the right room without one
    collision and never turns more than half a circle in place."""
    free = flat(door=0.56)
    grid = grid_of(free)
    assert int(grid.navigable[:, 60].sum()) == 3  # centre positions across the doorway
    for start in starts(free, 20, seed=1, x_max=2.4):
        reached, collisions, spin, _ = walk(free, free, start, (4.5, 2.0))
        assert reached and collisions == 0 and spin <= 6, (start, collisions, spin)


def test_a_coffee_table_below_the_cameras_view_is_passed_after_at_most_two_bumps() -> None:
    """A 0.5 m x 0.9 m table between start and goal, missing from the map (the camera at
    0.88 m does not see a 0.42 m top from within 0.75 m): an unexplained bump marks a
    0.6 m edge and the agent goes round. 24 random starts and goals either side."""
    sim = flat(door=None)
    box(sim, 2.8, 1.55, 3.3, 2.45)
    rng = np.random.default_rng(5)
    for _ in range(24):
        start = AgentState(1.0, rng.uniform(1.3, 2.7), rng.uniform(-0.7, 0.7))
        goal = (5.0, rng.uniform(1.0, 3.0))
        reached, collisions, spin, _ = walk(sim, flat(door=None), start, goal)
        assert reached and collisions <= 2 and spin <= 12, (start, goal, collisions, spin)


@pytest.mark.parametrize("door", [0.9, 0.6])
def test_bench_doorways_are_crossed_without_a_collision_from_anywhere(door: float) -> None:
    """The benchmark's doors are 0.9 m; 0.6 m is a tight one."""
    free = flat(door=door)
    for start in starts(free, 10, seed=2, x_max=2.6):
        reached, collisions, _, _ = walk(free, free, start, (5.2, 0.6))
        assert reached and collisions == 0, (start, collisions)


def test_a_doorway_the_body_cannot_take_is_marked_on_back_off_and_the_agent_moves_on() -> None:
    """A 0.47 m doorway on the straight way and a 0.9 m one aside. The planner routes
    through the narrow one (its centre cells clear the body), but from some approaches no
    step of the agent's 30-degree headings that fits the body makes progress there: it
    backs off, and without a mark the same plan brings it back (house-tune s01-000: 250
    steps between two cells). Marked, the step it could not take is planned around: a
    walk backs off at most twice, and more walks arrive."""
    free = flat(door=0.47, middle=2.025)
    xs = (np.arange(free.shape[1]) + 0.5) * CELL
    ys = (np.arange(free.shape[0]) + 0.5) * CELL
    free[np.ix_((ys >= 3.0) & (ys <= 3.9), (xs >= 2.95) & (xs <= 3.05))] = True  # wide door
    marked = [walk(free, free, s, (4.5, 2.0), max_steps=200) for s in starts(free, 12, 3, 2.4)]
    bare = [
        walk(free, free, s, (4.5, 2.0), max_steps=200, mark_back_off=False)
        for s in starts(free, 12, 3, 2.4)
    ]
    assert max(w[3] for w in marked) <= 2, [w[3] for w in marked]
    assert max(w[3] for w in bare) > 50  # the case is exercised: without marks it oscillates
    assert sum(w[0] for w in marked) > sum(w[0] for w in bare)


def test_a_bend_no_step_can_take_is_closed_across_and_the_agent_goes_round() -> None:
    """Two 0.5 m doorways 0.5 m apart, offset 0.5 m: the plan threads the S-bend, but from
    some approaches no step at all lowers the cost-to-go (the way bends sooner than a step)
    and the agent backs off with nothing to mark (house-tune s02-004: 70 steps between two
    cells). Closed across the way the plan leaves by, the bend is planned round through the
    wide way beside it."""
    free = flat(door=None)
    for x, middle in ((3.0, 2.025), (3.5, 2.525)):
        box(free, x - 0.05, 0.0, x + 0.05, middle - 0.25 - 1e-6)
        box(free, x - 0.05, middle + 0.25 + 1e-6, x + 0.05, 4.0)
    xs = (np.arange(free.shape[1]) + 0.5) * CELL
    ys = (np.arange(free.shape[0]) + 0.5) * CELL
    free[np.ix_((ys >= 3.2) & (ys <= 3.95), (xs >= 2.9) & (xs <= 3.6))] = True  # the wide way
    marked = [walk(free, free, s, (4.5, 2.0), max_steps=200) for s in starts(free, 8, 3, 2.4)]
    bare = [
        walk(free, free, s, (4.5, 2.0), max_steps=200, mark_back_off=False)
        for s in starts(free, 8, 3, 2.4)
    ]
    assert max(w[3] for w in bare) > 50  # the case is exercised: unmarked it oscillates
    assert all(w[0] for w in marked) and max(w[3] for w in marked) <= 2, marked
