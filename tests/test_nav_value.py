"""The Eq. 7 value map against its direct double sum, the scorer, and the egocentric map."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map.grid import IndexGrid
from glmap_tools.nav import (
    EgocentricValueMap,
    EmbeddingScorer,
    UnitText,
    Window,
    value_map_from_scores,
    value_map_reference,
)


def small_grid() -> IndexGrid:
    """Two instances and a region over both (cells overlap, as in a real map)."""
    grid = IndexGrid(0.05)
    grid.set_unit(1, [(i, j) for i in range(2, 5) for j in range(3, 6)])
    grid.set_unit(2, [(12, 9), (13, 9), (13, 10)])
    grid.set_unit(3, grid.cells_of_unit(1) | grid.cells_of_unit(2))
    grid.set_unit(4, [(-3, -2)])  # outside the window below: must not contribute
    return grid


@pytest.mark.parametrize("unit_mass", ["unit", "cells"])
@pytest.mark.parametrize("sigma", [0.05, 0.12, 0.3])
def test_the_fast_value_map_equals_the_explicit_double_sum_of_eq_7(
    sigma: float, unit_mass: str
) -> None:
    grid = small_grid()
    window = Window(0, 0, 16, 18)
    scores = {1: 0.9, 2: 0.4, 3: 0.25, 4: 1.0}
    fast = value_map_from_scores(scores, grid, window, sigma, unit_mass=unit_mass)
    ref = value_map_reference(scores, grid, window, sigma, unit_mass=unit_mass)
    assert fast.scale == ref.scale == 1.0  # in score units whatever the mass
    np.testing.assert_allclose(fast.values, ref.values, rtol=0, atol=1e-12)
    assert fast.peak == pytest.approx(ref.peak, rel=1e-12)
    assert fast.values.max() == pytest.approx(1.0)
    assert fast.origin == (0, 0) and fast.values.shape == (16, 18)


@pytest.mark.parametrize("sigma_cells", [2.0, 4.0])
def test_one_scored_cell_spreads_as_the_gaussian_of_eq_7_analytically(sigma_cells: float) -> None:
    """H(l) / H(p_u) = exp(-|l - p_u|^2 / (2 sigma^2)) around a lone one-cell unit: the kernel's
    own width, checked against the closed form (fast and reference share the kernel)."""
    cell = 0.05
    grid = IndexGrid(cell)
    grid.set_unit(1, [(20, 20)])
    vm = value_map_from_scores({1: 0.8}, grid, Window(0, 0, 41, 41), sigma_cells * cell)
    row = vm.values[20]  # the unit's row; H = 1 at its cell (Z = the peak)
    d = np.arange(41) - 20
    expected = np.exp(-(d**2) / (2 * sigma_cells**2))
    inside = np.abs(d) <= math.ceil(3 * sigma_cells)  # the kernel is cut at 3 sigma
    np.testing.assert_allclose(row[inside], expected[inside], rtol=1e-9, atol=1e-12)
    assert not row[~inside].any()
    diagonal = vm.values[20 + 2, 20 + 2]  # separable: the product of the axes' factors
    assert diagonal == pytest.approx(math.exp(-8 / (2 * sigma_cells**2)), rel=1e-9)


def test_the_value_map_peaks_on_the_best_unit_and_lists_separate_top_cells() -> None:
    grid = small_grid()
    vm = value_map_from_scores({1: 0.2, 2: 0.9}, grid, Window(0, 0, 16, 18), 0.1)
    x, y = vm.argmax_xy()  # type: ignore[misc]
    assert grid.cell_of(x, y) in grid.cells_of_unit(2)
    top = vm.top_cells(3, min_separation=0.3)
    assert top[0][2] == pytest.approx(1.0)
    assert all(math.dist(a[:2], b[:2]) >= 0.3 for a in top for b in top if a is not b)


def test_a_map_where_nothing_scores_is_empty_and_has_no_maximum() -> None:
    vm = value_map_from_scores({1: 0.0}, small_grid(), Window(0, 0, 8, 8), 0.2)
    assert vm.empty and vm.argmax_xy() is None and vm.top_cells() == []
    with pytest.raises(InvalidInputError, match="must be in"):
        value_map_from_scores({1: 1.5}, small_grid(), Window(0, 0, 8, 8), 0.2)


def test_the_embedding_scorer_maps_cosines_to_zero_one_and_ranks_the_matching_text_first() -> None:
    scorer = EmbeddingScorer(HashingEmbedder())
    units = [
        UnitText(1, "instance", "a red chair with four legs"),
        UnitText(2, "instance", "a wooden table"),
        UnitText(3, "region", "a kitchen with a stove"),
    ]
    s = scorer.score("red chair", units)
    assert s.shape == (3,) and np.all((s >= 0) & (s <= 1))
    assert int(np.argmax(s)) == 0
    assert scorer.score("a wooden table", [units[1]])[0] == pytest.approx(1.0, abs=1e-6)
    with pytest.raises(InvalidInputError, match="goal"):
        scorer.score("  ", units)


def test_the_egocentric_map_fills_the_view_cone_and_fuses_by_confidence() -> None:
    boxes = scenes.floor(6.0) + [scenes.Box((3.0, -3.0, 0.0), (3.2, 3.0, 2.0), (0.7, 0.7, 0.7), 0)]
    frame, _ = scenes.view(boxes, (0.0, 0.0, 0.9), (1.0, 0.0, 0.9), 80, 60)
    ego = EgocentricValueMap(0.05)
    n = ego.add_frame(frame, 0.8)
    assert n > 100
    vm = ego.as_value_map()
    assert vm.value_at(2.0, 0.0) == pytest.approx(0.8)  # on the optical axis, before the wall
    assert vm.value_at(-1.0, 0.0) == 0.0  # behind the camera
    assert vm.value_at(4.0, 0.0) == 0.0  # behind the wall
    ego.add_frame(frame, 0.2)  # same view, same confidences: the plain mean
    assert ego.as_value_map().value_at(2.0, 0.0) == pytest.approx(0.5)
    # Off-axis cells are trusted less: a confident on-axis view outweighs them.
    assert ego.confidence.max() <= 1.0 + 1e-9


@pytest.mark.parametrize("heading", [0.0, 0.5, math.pi / 2, 2.8, math.pi, -2.0, -math.pi / 2])
def test_the_view_cone_is_the_same_from_the_sector_as_from_the_whole_square(
    heading: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """view_cone looks only at the cells of the view's sector; those of the whole square
    around the camera give the same cells and confidences, in the same order."""
    from glmap_tools.nav import egocentric

    boxes = scenes.floor(12.0)
    for x, y in ((4.0, 0.0), (0.0, 4.0), (-4.0, 0.0), (0.0, -4.0)):
        boxes.append(scenes.Box((x - 0.3, y - 0.3, 0.0), (x + 0.3, y + 0.3, 2.0), (0.6,) * 3, 0))
    eye = (0.3, -0.2, 0.9)
    look = (eye[0] + math.cos(heading), eye[1] + math.sin(heading), 0.9)
    frame, _ = scenes.view(boxes, eye, look, 80, 60)
    ego = EgocentricValueMap(0.05)
    cells, conf = ego.view_cone(frame)
    monkeypatch.setattr(egocentric, "_within", lambda *_: True)  # every axis: the square
    all_cells, all_conf = ego.view_cone(frame)
    assert len(cells) > 100
    np.testing.assert_array_equal(cells, all_cells)
    np.testing.assert_array_equal(conf, all_conf)


def test_per_unit_mass_gives_every_unit_its_score_in_total_whatever_its_area() -> None:
    from glmap_tools.nav import NavConfig
    from glmap_tools.nav.value import per_unit_mass, score_image

    grid = small_grid()  # unit 1: 9 cells, unit 2: 3 cells, unit 3: both (12)
    window = Window(0, 0, 16, 18)
    scores = {1: 0.3, 2: 0.5}
    spread = per_unit_mass(scores, grid)
    assert spread == {1: pytest.approx(0.3 / 9), 2: pytest.approx(0.5 / 3)}
    for uid, s in scores.items():
        assert score_image({uid: spread[uid]}, grid, window).sum() == pytest.approx(s)
    # Summed over cells, the 9-cell unit outweighs the better 3-cell one; spread, it does not.
    by_cells = value_map_from_scores(scores, grid, window, 0.15, unit_mass="cells").argmax_xy()
    by_unit = value_map_from_scores(scores, grid, window, 0.15).argmax_xy()
    assert (
        by_unit == value_map_from_scores(spread, grid, window, 0.15, unit_mass="cells").argmax_xy()
    )
    assert grid.cell_of(*by_cells) in grid.cells_of_unit(1)  # type: ignore[misc]
    assert grid.cell_of(*by_unit) in grid.cells_of_unit(2)  # type: ignore[misc]
    with pytest.raises(InvalidInputError, match="unit_mass='units'.*Did you mean 'unit'"):
        NavConfig(unit_mass="units")
    with pytest.raises(InvalidInputError, match="unit_mass='area' must be 'unit' or 'cells'"):
        value_map_from_scores(scores, grid, window, 0.15, unit_mass="area")
    assert NavConfig().unit_mass == "unit"  # measured on tune (nav/design.md)


def test_nav_core_config_overrides_name_a_wrong_field_and_refuse_bad_values() -> None:
    from glmap_tools.bench.nav_core import config_overrides

    assert config_overrides(["clearance_cost=2", "unit_mass=cells"]) == {
        "clearance_cost": 2,
        "unit_mass": "cells",
    }
    with pytest.raises(InvalidInputError, match="clearance_cost"):
        config_overrides(["clearance_cots=2"])  # did you mean
    with pytest.raises(InvalidInputError, match="must be a number >= 0"):
        config_overrides(["clearance_cost=-1"])
