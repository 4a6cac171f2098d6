"""The FMM planner (clearance cost) against its Dijkstra reference, obstacle inflation, and
the next action of the cost-to-go controller."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, DenseOccupancy
from glmap_tools.nav import (
    DIJKSTRA8_MAX_RATIO,
    NavConfig,
    OutsideMapError,
    UnreachableGoalError,
    drive,
    geodesic,
    inflate,
    plan,
    reference_geodesic,
)
from glmap_tools.nav.grid import inflate_reference
from glmap_tools.nav.motion import body_radius, clearance, masks

CELL = 0.05
# FMM is isotropic; 8-connected Dijkstra pays up to DIJKSTRA8_MAX_RATIO (8.24 %) on straight
# lines between the 8 directions. Near obstacles both hug corners on the grid, and FMM's
# first cells around the source carry a discretisation error of about half a cell, so the
# ratio is held in [1 - 3 %, DIJKSTRA8_MAX_RATIO + 3 %] for cells at least 10 cells away.
LOW, HIGH = 0.97, DIJKSTRA8_MAX_RATIO + 0.03


def room(h: int = 60, w: int = 80) -> np.ndarray:
    """[h, w] int8 state: a FREE room with OBSTACLE walls all round."""
    state = np.full((h, w), FREE, dtype=np.int8)
    state[0, :] = state[-1, :] = state[:, 0] = state[:, -1] = OBSTACLE
    return state


def random_plannable(seed: int, h: int, w: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ok = np.ones((h, w), dtype=bool)
    for _ in range(6):  # a few rectangular obstacles
        r, c = rng.integers(0, h - 8), rng.integers(0, w - 8)
        ok[r : r + rng.integers(2, 12), c : c + rng.integers(2, 12)] = False
    return ok


def _scikit_fmm_geodesic(
    trav: np.ndarray, goal: tuple[int, int], cell: float, speed: np.ndarray, band: float
) -> np.ndarray:
    """`geodesic` through scikit-fmm's `travel_time` (what the planner marched with before
    its own marcher, and what every recorded episode and table was measured with)."""
    import skfmm  # the dev extra's reference (.ci/setup installs it)

    mask = ~trav
    mask[goal] = False
    phi = np.ones(trav.shape)
    phi[goal] = -1.0
    f = np.where(mask | ~(speed > 0), 1.0, speed)
    t = skfmm.travel_time(np.ma.MaskedArray(phi, mask), f, dx=cell, narrow=band)
    out = np.ma.getdata(t).astype(np.float64) + 0.5 * cell / float(f[goal])
    out[np.ma.getmaskarray(t)] = np.inf
    out[goal] = 0.0
    return out


def random_march(seed: int) -> tuple[np.ndarray, tuple[int, int], float, np.ndarray, float]:
    """A random march: obstacles (rectangles and scattered cells), a speed field (uniform,
    so times tie, or varied as the clearance cost varies it), a source (borders included),
    a cell size and a band (0: the whole grid)."""
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(1, 70)), int(rng.integers(1, 70))
    trav = rng.random((h, w)) > rng.uniform(0.0, 0.3)
    for _ in range(int(rng.integers(0, 6))):
        r, c = int(rng.integers(0, h)), int(rng.integers(0, w))
        trav[r : r + int(rng.integers(1, 15)), c : c + int(rng.integers(1, 15))] = False
    kind = seed % 3
    if kind == 0:
        speed = np.full((h, w), float(rng.uniform(0.2, 2.0)))
    elif kind == 1:
        speed = rng.uniform(0.05, 1.0, (h, w))
    else:  # smooth, as 1 / clearance cost
        rows, cols = np.mgrid[0:h, 0:w]
        speed = 0.6 + 0.4 * np.sin(rows / 4.0 + rng.uniform(0, 6)) * np.cos(cols / 5.0)
    speed = np.where(trav, speed, 0.0)
    goal = (int(rng.integers(0, h)), int(rng.integers(0, w)))
    cell = float(rng.choice([0.05, 0.1, 0.25, 1.0]))
    band = 0.0 if seed % 2 else float(rng.uniform(0.0, 0.5 * (h + w) * cell))
    return trav, goal, cell, speed, band


@pytest.mark.parametrize("block", range(4))
def test_the_marcher_gives_scikit_fmms_travel_times_bit_for_bit(block: int) -> None:
    """Every time and every unreached cell of `geodesic` equals scikit-fmm's `travel_time`
    on 150 random marches a block: blocked cells, tied times, bands, sources at borders."""
    marched = 0
    for seed in range(150 * block, 150 * (block + 1)):
        trav, goal, cell, speed, band = random_march(seed)
        field = geodesic(trav, goal, cell, speed, band if band > 0 else None)
        mask = ~trav
        mask[goal] = False
        h, w = trav.shape
        sides = [(goal[0] + dr, goal[1] + dc) for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1))]
        if not any(0 <= r < h and 0 <= c < w and not mask[r, c] for r, c in sides):
            continue  # fenced in: geodesic answers without a march
        marched += 1
        expected = _scikit_fmm_geodesic(trav, goal, cell, speed, max(band, 1e-9) if band else 0.0)
        np.testing.assert_array_equal(field, expected, err_msg=f"seed {seed}")
    assert marched > 100


@pytest.mark.parametrize(("seed", "h", "w"), [(0, 40, 40), (1, 60, 90), (2, 80, 50)])
def test_fmm_geodesic_agrees_with_dijkstra_within_the_stated_tolerance(
    seed: int, h: int, w: int
) -> None:
    ok = random_plannable(seed, h, w)
    rows, cols = np.nonzero(ok)
    k = len(rows) // 2
    src = (int(rows[k]), int(cols[k]))
    fast = geodesic(ok, src, CELL)
    ref = reference_geodesic(ok, src, CELL)
    assert np.array_equal(np.isfinite(fast), np.isfinite(ref))
    far = np.isfinite(ref) & (ref >= 10 * CELL)
    ratio = ref[far] / fast[far]
    assert ratio.min() >= LOW, ratio.min()
    assert ratio.max() <= HIGH, ratio.max()


def test_fmm_is_exact_along_an_axis_and_shorter_than_dijkstra_off_the_8_directions() -> None:
    ok = np.ones((41, 101), dtype=bool)
    fast = geodesic(ok, (20, 0), CELL)
    ref = reference_geodesic(ok, (20, 0), CELL)
    assert fast[20, 100] == pytest.approx(100 * CELL, rel=0.01)
    # (20 rows, 50 cols): about 22 deg off the axis, where 8-connected paths are worst.
    true = math.hypot(20, 50) * CELL
    assert fast[0, 50] == pytest.approx(true, rel=0.02)
    assert ref[0, 50] / true > 1.07


@pytest.mark.parametrize("radius", [0.9, 2.5, 3.6, 5.0])
def test_row_wise_inflation_equals_binary_dilation_with_a_disk(radius: float) -> None:
    mask = np.random.default_rng(3).random((50, 70)) < 0.03
    assert np.array_equal(inflate(mask, radius), inflate_reference(mask, radius))


def occ_of(state: np.ndarray, origin: tuple[int, int] = (-10, -20)) -> DenseOccupancy:
    return DenseOccupancy(state, origin, CELL)


@pytest.mark.parametrize(("seed", "h", "w"), [(0, 40, 40), (1, 60, 90), (2, 80, 50)])
def test_fmm_with_the_clearance_cost_agrees_with_dijkstra_on_the_same_cost(
    seed: int, h: int, w: int
) -> None:
    """The cost-to-go the agent follows (speed = 1 / clearance cost) against Dijkstra-8 on
    the same per-cell cost: the same bounds as in metres."""
    ok = random_plannable(seed, h, w)
    state = np.where(ok, FREE, OBSTACLE).astype(np.int8)
    occ = occ_of(state)
    rows, cols = np.nonzero(state == FREE)
    clear = clearance(occ)
    open_ = clear >= body_radius(NavConfig(), CELL)
    k = int(np.argmax(np.where(open_[rows, cols], clear[rows, cols], -1)))
    src = (int(rows[k]), int(cols[k]))
    _, plannable_, speed = masks(occ, clear, src, NavConfig())
    assert (speed[plannable_] > 0).all() and (speed[plannable_] <= 1).all()
    assert speed[plannable_].min() < 0.5  # the cost does rise near obstacles here
    fast = geodesic(plannable_, src, CELL, speed)
    ref = reference_geodesic(plannable_, src, CELL, speed)
    assert np.array_equal(np.isfinite(fast), np.isfinite(ref))
    far = np.isfinite(ref) & (ref >= 10 * CELL)
    ratio = ref[far] / fast[far]
    assert ratio.min() >= LOW, ratio.min()
    assert ratio.max() <= HIGH, ratio.max()


@pytest.mark.parametrize(
    ("seed", "h", "w", "with_speed"), [(0, 40, 40, True), (1, 60, 90, True), (2, 80, 50, False)]
)
def test_a_march_stopped_at_a_band_gives_the_whole_marchs_values_inside_it(
    seed: int, h: int, w: int, with_speed: bool
) -> None:
    ok = random_plannable(seed, h, w)
    state = np.where(ok, FREE, OBSTACLE).astype(np.int8)
    occ = occ_of(state)
    clear = clearance(occ)
    rows, cols = np.nonzero(ok)
    src = (int(rows[len(rows) // 3]), int(cols[len(rows) // 3]))
    speed = masks(occ, clear, src, NavConfig())[2] if with_speed else None
    whole = geodesic(ok, src, CELL, speed)
    for band in (0.3, 1.0, 2.5):
        part = geodesic(ok, src, CELL, speed, band)
        inside = np.isfinite(part)
        assert np.array_equal(part[inside], whole[inside])  # the same bits
        assert (whole[~inside] >= band).all()  # every cell costing less is inside
        assert inside.sum() < np.isfinite(whole).sum()


@pytest.mark.parametrize("estimate_scale", [0.2, 1.0, 5.0])
def test_the_cost_to_go_is_the_whole_march_wherever_the_agent_reads_it(
    estimate_scale: float,
) -> None:
    from glmap_tools.nav.planner import cost_to_go

    ok = random_plannable(1, 60, 90)
    state = np.where(ok, FREE, OBSTACLE).astype(np.int8)
    occ = occ_of(state)
    clear = clearance(occ)
    rows, cols = np.nonzero(ok)
    end, agent = (int(rows[10]), int(cols[10])), (int(rows[-10]), int(cols[-10]))
    speed = masks(occ, clear, agent, NavConfig())[2]
    whole = geodesic(ok, end, CELL, speed)
    reach = 7
    got = cost_to_go(ok, end, agent, CELL, speed, estimate_scale * whole[agent], reach)
    r, c = agent
    window = (slice(r - reach, r + reach + 1), slice(c - reach, c + reach + 1))
    assert np.array_equal(got[window], whole[window])  # a band too narrow: the whole march
    assert np.array_equal(got[got <= whole[agent]], whole[whole <= whole[agent]])


@pytest.mark.parametrize("stride", [1, 2])
def test_a_plan_runs_from_agent_to_goal_through_the_middle_of_a_gap(stride: int) -> None:
    """A wall with a 1.0 m gap and the goal past its top end: the path keeps the body radius
    from every obstacle cell and crosses the gap at least 0.375 m from either jamb (the
    clearance cost; the shortest path in metres would shave the top jamb at 0.205 m)."""
    state = room()
    state[5:55, 40] = OBSTACLE
    state[20:40, 40] = FREE  # the gap: rows 20..39, middle 29.5
    occ = occ_of(state)
    start, goal = occ.index_to_world(8, 20), occ.index_to_world(8, 60)
    out = plan(occ, start, 0.0, goal, NavConfig(plan_stride=stride))
    assert out.reachable
    np.testing.assert_allclose(out.path[0], start)
    np.testing.assert_allclose(out.path[-1], goal)
    clear = clearance(occ)
    cells = [occ.world_to_index(x, y) for x, y in out.path[1:-1]]
    assert min(clear[r, c] for r, c in cells) >= body_radius(NavConfig(), CELL)
    crossing = [clear[r, c] for r, c in cells if c == 40]
    assert crossing and min(crossing) >= 0.375, crossing
    polyline = float(np.linalg.norm(np.diff(out.path, axis=0), axis=1).sum())
    assert out.length == pytest.approx(polyline)
    assert out.length >= math.dist(start, goal)


def test_facing_an_open_path_moves_forward_behind_turns_and_a_blocked_step_turns_away() -> None:
    """`drive` on a free room with the cost-to-go to a point 1 m east of the agent."""
    config = NavConfig()
    occ = occ_of(room())
    here = occ.index_to_world(30, 30)
    goal_rc = (30, 50)
    clear = clearance(occ)
    _, ok, speed = masks(occ, clear, occ.world_to_index(*here), config)
    to_go = geodesic(ok, goal_rc, CELL, speed)
    assert drive(occ, clear, to_go, here, 0.0, config).action == "move_forward"
    assert drive(occ, clear, to_go, here, math.radians(10), config).action == "move_forward"
    assert drive(occ, clear, to_go, here, math.radians(-90), config).action == "turn_left"
    assert drive(occ, clear, to_go, here, math.radians(90), config).action == "turn_right"
    back = drive(occ, clear, to_go, here, math.pi, config)
    assert back.action in ("turn_left", "turn_right") and abs(back.turns) == 6
    # An obstacle cell right ahead: the step is not open, the agent turns to step round it.
    state = room()
    state[30, 34] = OBSTACLE
    occ2 = occ_of(state)
    clear2 = clearance(occ2)
    _, ok2, speed2 = masks(occ2, clear2, occ2.world_to_index(*here), config)
    to_go2 = geodesic(ok2, goal_rc, CELL, speed2)
    step = drive(occ2, clear2, to_go2, here, 0.0, config)
    assert step.action in ("turn_left", "turn_right") and step.open and abs(step.turns) <= 3


def test_plan_stops_at_the_goal_and_turns_when_the_goal_is_behind() -> None:
    occ = occ_of(room())
    here = occ.index_to_world(30, 40)
    assert plan(occ, here, 0.0, here).action == "stop"
    behind = occ.index_to_world(30, 20)
    assert plan(occ, here, 0.0, behind).action in ("turn_left", "turn_right")
    assert plan(occ, here, math.pi, behind).action == "move_forward"


def test_plan_stops_within_half_a_step_of_the_goal_and_not_beyond() -> None:
    occ = occ_of(room())
    here = occ.index_to_world(30, 40)
    half = NavConfig().forward_step / 2
    near = (here[0] + half - 0.005, here[1])
    far = (here[0] + half + 0.005, here[1])
    assert plan(occ, here, 0.0, near).action == "stop"
    assert plan(occ, here, 0.0, far).action == "move_forward"


def test_an_enclosed_goal_is_unreachable_and_the_error_names_the_nearest_reachable_point() -> None:
    state = room()
    state[20:40, 50] = state[20:40, 70] = state[20, 50:71] = state[40, 50:71] = OBSTACLE
    occ = occ_of(state)
    start, goal = occ.index_to_world(30, 10), occ.index_to_world(30, 60)
    with pytest.raises(UnreachableGoalError, match="Nearest reachable point") as info:
        plan(occ, start, 0.0, goal)
    assert info.value.nearest_xy is not None
    near = info.value.nearest_xy
    # Just outside the box's walls by the body radius (4.1 cells): 15 cells from the goal.
    assert math.dist(near, goal) == pytest.approx(15 * CELL)
    assert plan(occ, start, 0.0, near).reachable
    loose = plan(occ, start, 0.0, goal, strict=False)
    assert not loose.reachable and math.isfinite(loose.length)
    assert loose.goal_xy == pytest.approx(info.value.nearest_xy)


def test_unknown_space_is_crossed_only_when_planning_is_optimistic() -> None:
    state = room()
    state[:, 40] = OBSTACLE
    state[25:35, 40] = UNKNOWN  # an unseen stretch of the dividing wall
    occ = occ_of(state)
    start, goal = occ.index_to_world(30, 20), occ.index_to_world(30, 60)
    assert plan(occ, start, 0.0, goal, NavConfig(optimistic=True)).reachable
    with pytest.raises(UnreachableGoalError):
        plan(occ, start, 0.0, goal, NavConfig(optimistic=False))


def test_an_agent_or_goal_outside_the_window_is_refused() -> None:
    occ = occ_of(room())
    inside = occ.index_to_world(30, 40)
    with pytest.raises(OutsideMapError, match="agent position"):
        plan(occ, (100.0, 100.0), 0.0, inside)
    with pytest.raises(OutsideMapError, match="goal position"):
        plan(occ, inside, 0.0, (-100.0, 0.0))


def test_a_boxed_in_agent_reaches_nothing_and_plans_say_so() -> None:
    field = geodesic(np.zeros((5, 5), dtype=bool), (2, 2), CELL)
    assert field[2, 2] == 0.0 and np.isinf(np.delete(field.ravel(), 12)).all()
    state = room(30, 30)
    state[10:21, 10] = state[10:21, 20] = state[10, 10:21] = state[20, 10:21] = OBSTACLE
    occ = occ_of(state)
    inside, outside = occ.index_to_world(15, 15), occ.index_to_world(25, 25)
    with pytest.raises(UnreachableGoalError):
        plan(occ, inside, 0.0, outside)


def test_a_goal_fenced_in_by_blocked_cells_with_free_cells_elsewhere_is_unreachable() -> None:
    # A 9x9 grid: a free strip at the left edge, the goal in the middle of a blocked block.
    trav = np.zeros((9, 9), dtype=bool)
    trav[:, 0] = True
    field = geodesic(trav, (4, 4), 0.1)
    assert field[4, 4] == 0.0
    assert np.isinf(np.delete(field.ravel(), 4 * 9 + 4)).all()
    # Free cells touching the goal only diagonally: FMM's axis stencil cannot start there.
    trav[3, 3] = trav[5, 5] = True
    field = geodesic(trav, (4, 4), 0.1, speed=np.ones((9, 9)))
    assert np.isinf(field[:, 0]).all()


@settings(max_examples=200, deadline=None)
@given(
    shape=st.tuples(st.integers(2, 12), st.integers(2, 12)),
    data=st.data(),
    with_speed=st.booleans(),
)
def test_geodesic_over_random_grids_returns_a_field_and_never_raises(
    shape: tuple[int, int], data: st.DataObject, with_speed: bool
) -> None:
    h, w = shape
    cells = data.draw(st.lists(st.booleans(), min_size=h * w, max_size=h * w))
    trav = np.array(cells, dtype=bool).reshape(h, w)
    goal = (data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1)))
    speed = np.full((h, w), 0.5) if with_speed else None
    field = geodesic(trav, goal, 0.05, speed=speed)
    reference = reference_geodesic(trav, goal, 0.05, speed=speed)
    assert field.shape == (h, w) and field[goal] == 0.0
    # A finite cost exactly where the 8-connected reference reaches (FMM may also cut a
    # diagonal the reference refuses, never the other way round).
    assert not (np.isinf(field) & np.isfinite(reference)).any()
