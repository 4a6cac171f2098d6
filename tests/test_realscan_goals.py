"""Goal matching on real rooms (issue 40): tied units keep one goal step after step, and
units the agent cannot reach or recognise (a ceiling light 2.7 m up) hold no goal."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav import NavConfig
from glmap_tools.nav.config import GOAL_MAX_BOTTOM, GOAL_MIN_SIZE
from glmap_tools.nav.perceive import find_goal_match, unfit_goals
from glmap_tools.nav.policy import NavState, decide
from glmap_tools.nav.scorers import UnitText
from glmap_tools.sim import episodes

# A bedroom of our own: a bed, a bedside lamp on the floor-standing nightstand, a ceiling
# light over the room's middle. Both lights are "a lamp" to the detector.
TEXTS = {
    1: ("lamp", "a white lamp"),  # the ceiling light, seen first: the lower id
    2: ("lamp", "a white lamp"),  # the bedside lamp
    3: ("bed", "a double bed with a grey cover"),
}


def bedroom() -> list[scenes.Box]:
    white, grey = (0.95, 0.95, 0.9), (0.5, 0.5, 0.55)
    return (
        scenes.floor(6.0)
        + [scenes.Box((-0.25, 1.5, 2.6), (0.25, 2.0, 2.7), white, 1)]
        + [scenes.Box((1.4, 1.4, 0.0), (1.7, 1.7, 0.9), white, 2)]
        + [scenes.Box((-1.0, 2.2, 0.0), (1.0, 4.2, 0.5), grey, 3)]
    )


@pytest.fixture(scope="module")
def seen() -> GLMap:
    boxes = bedroom()
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    views = [((0.0, 0.6, 0.88), (0.0, 1.75, 2.65))] * 2  # looking up at the ceiling light
    views += [((0.0, -1.0, 0.88), (1.55, 1.55, 0.5))] * 2
    views += [((0.0, -1.0, 0.88), (0.0, 3.0, 0.3))] * 2
    for eye, target in views:
        frame, ids = scenes.view(boxes, eye, target, 320, 240)
        glmap.integrate(frame, scenes.semantics(ids, TEXTS))
    return glmap


def _lights(glmap: GLMap) -> tuple[int, int]:
    """(ceiling light id, bedside lamp id) in the map."""
    lamps = [u for u in glmap.instances.values() if u.label == "lamp"]
    assert len(lamps) == 2, [(u.id, u.label) for u in glmap.instances.values()]
    high = max(lamps, key=lambda u: float(u.bounds()[0][2]))
    low = min(lamps, key=lambda u: float(u.bounds()[0][2]))
    return high.id, low.id


def test_the_goal_rule_of_the_simulator_and_of_the_agent_is_one_rule() -> None:
    assert (GOAL_MIN_SIZE, GOAL_MAX_BOTTOM) == (episodes.MIN_GOAL_SIZE, episodes.MAX_GOAL_BOTTOM)


def test_a_ceiling_light_is_unfit_as_a_goal_and_the_bedside_lamp_is_matched(seen) -> None:
    high, low = _lights(seen)
    assert high < low  # the ceiling light would win a tie by id
    unfit = unfit_goals(seen)
    assert set(unfit) == {high} and "m up" in unfit[high]
    config = NavConfig(stop_threshold=0.5, initial_spin=0)
    state = NavState()
    for _ in range(3):
        d = decide(seen, (0.0, -1.0), math.pi / 2, "a white lamp", config=config, state=state)
        assert d.matched_unit == low, d.waypoint.reason


class _Grid:
    def cells_of_unit(self, uid):  # type: ignore[no-untyped-def]
        return frozenset({(uid, 0)})


class _Map:
    grid = _Grid()
    instances: dict = {}  # no Gaussians: a match's footprint is its grid cells


def test_tied_units_go_to_the_previous_match_else_to_the_lowest_id() -> None:
    units = [UnitText(u, "instance", "a lamp", observations=3, label="lamp") for u in (9, 4, 7)]
    scores = np.array([0.9230004, 0.923, 0.9230001])  # the same text, float noise apart
    config = NavConfig(stop_threshold=0.56)
    first = find_goal_match(_Map(), units, scores, set(), config)  # type: ignore[arg-type]
    assert first is not None and first.unit_id == 4
    kept = find_goal_match(_Map(), units, scores, set(), config, prefer=7)  # type: ignore[arg-type]
    assert kept is not None and kept.unit_id == 7
    # A clearly better unit wins over the previous match.
    better = np.array([0.95, 0.923, 0.9230001])
    won = find_goal_match(_Map(), units, better, set(), config, prefer=7)  # type: ignore[arg-type]
    assert won is not None and won.unit_id == 9
