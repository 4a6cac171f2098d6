"""A value map that is never empty without reason: below the evidence gate, the regions
whose text suggests the goal guide exploration (nav.value.evidence_scores)."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.grid import IndexGrid
from glmap_tools.nav import NavConfig, UnitText, Window, value_map_from_scores
from glmap_tools.nav.value import evidence_scores

LEAST = {"instance": 0.5, "region": 0.3}
BOTH = ("instance", "region")
UNITS = [
    UnitText(1, "instance", "a white refrigerator"),
    UnitText(2, "instance", "a red wooden chair"),
    UnitText(10, "region", "cooking area: a fridge and a stove, for preparing food"),
    UnitText(11, "region", "sleeping area: a bed and a nightstand"),
    UnitText(12, "region", "seating area: a sofa and a tv"),
]


def test_units_past_the_gate_are_the_evidence_and_regions_below_it_stay_out():
    scores = {1: 0.6, 2: 0.1, 10: 0.25, 11: 0.05, 12: 0.0}
    used, what = evidence_scores(UNITS, scores, BOTH, LEAST, region_hint=0.8)
    assert what == "units" and used == {1: 0.6}


def test_below_the_gate_the_best_regions_guide_and_weaker_ones_do_not():
    scores = {1: 0.4, 2: 0.1, 10: 0.25, 11: 0.21, 12: 0.1}
    used, what = evidence_scores(UNITS, scores, BOTH, LEAST, region_hint=0.8)
    assert what == "region hint" and used == {10: 0.25, 11: 0.21}  # 0.21 >= 0.8 * 0.25
    none, why = evidence_scores(UNITS, scores, BOTH, LEAST, region_hint=0.0)
    assert (none, why) == ({}, "none")  # Eq. 7 behind the gate alone, as before


def test_the_value_map_is_empty_only_when_no_region_says_anything_of_the_goal():
    nothing = {1: 0.4, 2: 0.0, 10: 0.0, 11: 0.0, 12: 0.0}
    assert evidence_scores(UNITS, nothing, BOTH, LEAST, 0.8) == ({}, "none")
    # A policy that reads instances only has no region to be guided by.
    some = {1: 0.4, 2: 0.0, 10: 0.2, 11: 0.0, 12: 0.0}
    assert evidence_scores(UNITS, some, ("instance",), LEAST, 0.8) == ({}, "none")


def test_the_hint_puts_the_value_map_peak_on_the_region_that_suggests_the_goal():
    grid = IndexGrid(0.05)
    grid.set_unit(10, [(i, j) for i in range(30, 36) for j in range(4, 8)])  # the kitchen
    grid.set_unit(11, [(i, j) for i in range(2, 8) for j in range(20, 26)])  # the bedroom
    grid.set_unit(1, [(4, 4)])
    scores = {1: 0.4, 2: 0.0, 10: 0.3 * 0.9, 11: 0.1, 12: 0.0}
    used, what = evidence_scores(UNITS, scores, BOTH, LEAST, region_hint=0.8)
    value = value_map_from_scores(used, grid, Window(0, 0, 30, 40), 0.5)  # 30 rows, 40 cols
    assert what == "region hint" and not value.empty
    x, y = value.argmax_xy()  # type: ignore[misc]
    assert 30 * 0.05 <= x <= 36 * 0.05 and 4 * 0.05 <= y <= 8 * 0.05
    assert value.value_at(4 * 0.05, 22 * 0.05) < 0.01  # the bedroom: a tail of K_sigma only


def test_region_hint_is_a_share_in_0_1():
    assert NavConfig(region_hint=0.8).region_hint == 0.8
    for bad in (-0.1, 1.5, np.nan):
        with pytest.raises(InvalidInputError, match="region_hint"):
            NavConfig(region_hint=bad)
