"""The pure steps of a policy step: choose_and_plan, progress, bump marks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav import NavConfig
from glmap_tools.nav.choose import PlanRequest, choose_and_plan, progress
from glmap_tools.nav.perceive import Bump, bump_marks, surroundings_of
from glmap_tools.nav.planner import Plan
from glmap_tools.nav.waypoint import Waypoint
from tests.test_nav_decide import CONFIG, TEXTS, walls


@pytest.fixture(scope="module")
def room() -> GLMap:
    """The walled room of test_nav_decide, seen from its centre in eight directions."""
    boxes = scenes.floor(6.0) + walls() + scenes.chair(1.2, 1.3, object_id=1)
    boxes += scenes.table(-1.0, -1.2, object_id=2)
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    for k in range(8):
        a = 2 * math.pi * k / 8
        frame, ids = scenes.view(boxes, (0, 0, 0.88), (math.cos(a), math.sin(a), 0.88), 96, 72)
        glmap.integrate(frame, scenes.semantics(ids, TEXTS))
    return glmap


def _request(glmap: GLMap, avoid=(), last=None, turns=0) -> PlanRequest:
    sur = surroundings_of(glmap, (0.0, 0.0), set(), CONFIG)
    return PlanRequest(None, sur, (0.0, 0.0), 0.0, None, None, CONFIG, last, turns, avoid)


def test_choosing_leaves_the_request_as_it_was_and_reports_what_it_gave_up(room) -> None:
    req = _request(room)
    first = choose_and_plan(req)
    assert first.waypoint.kind == "frontier" and first.plan.action != "stop"
    assert first.avoid == () and first.rejected == frozenset()
    # The chosen frontier given up: the next choice is elsewhere, the request unchanged.
    gave_up = _request(room, avoid=(first.waypoint.xy,))
    second = choose_and_plan(gave_up)
    assert gave_up.avoid == (first.waypoint.xy,)
    assert second.waypoint.xy != first.waypoint.xy
    assert second.avoid[:1] == (first.waypoint.xy,)


def test_a_frontier_waypoint_is_held_after_turning_in_place(room) -> None:
    wp = choose_and_plan(_request(room)).waypoint
    held = Waypoint(wp.xy, "frontier", None, 0.0, "the previous step's frontier")
    kept = choose_and_plan(_request(room, last=held, turns=6))
    assert kept.waypoint is held
    fresh = choose_and_plan(_request(room, last=held, turns=5))
    assert fresh.waypoint is not held


def _plan(length: float) -> Plan:
    return Plan(np.zeros((2, 2)), length, "move_forward", True, (1.0, 0.0))


def test_progress_gives_up_a_frontier_the_agent_does_not_close_in_on() -> None:
    config = NavConfig(stuck_steps=3)
    wp = Waypoint((3.0, 0.0), "frontier", None, 0.0, "")
    p = progress(None, math.inf, 0, wp, _plan(3.0), config)
    assert (p.best_distance, p.since_progress, p.give_up) == (3.0, 0, None)
    for expected in (1, 2):
        p = progress(wp, p.best_distance, p.since_progress, wp, _plan(2.9), config)
        assert (p.since_progress, p.give_up) == (expected, None)
    p = progress(wp, p.best_distance, p.since_progress, wp, _plan(2.9), config)
    assert (p.best_distance, p.since_progress, p.give_up) == (math.inf, 0, (3.0, 0.0))


@pytest.mark.parametrize("kind", ["goal", "frontier"])
def test_progress_resets_on_a_new_waypoint_and_never_gives_up_the_goal(kind) -> None:
    config = NavConfig(stuck_steps=1)
    wp = Waypoint((3.0, 0.0), kind, None, 0.0, "")
    p = progress(wp, 2.9, 0, wp, _plan(2.9), config)
    assert p.give_up == (None if kind == "goal" else (3.0, 0.0))
    elsewhere = Waypoint((0.0, 3.0), kind, None, 0.0, "")
    assert progress(wp, 2.9, 5, elsewhere, _plan(2.9), config).since_progress == 0


def test_only_a_forward_move_stopped_short_leaves_bump_marks(room) -> None:
    config = CONFIG
    here = (0.0, 0.0)
    assert bump_marks(room, here, "turn_left", here, 0.0, config).cells == set()
    full_step = bump_marks(room, here, "move_forward", (-config.forward_step, 0.0), 0.0, config)
    assert full_step.cells == full_step.contact == set()
    stopped = bump_marks(room, here, "move_forward", here, 0.0, config)  # did not move at all
    assert stopped.cells and len(stopped.contact) == 1 and stopped.contact <= stopped.cells


def _hall(width: float) -> GLMap:
    """A hall `width` m wide along +x from a closed end at x = -0.4, seen both ways."""
    grey, h, t = (0.8, 0.8, 0.8), 2.0, 0.1
    half = width / 2
    boxes = scenes.floor(6.0) + [
        scenes.Box((-0.5, -half - t, 0), (3.0, -half, h), grey, 0),
        scenes.Box((-0.5, half, 0), (3.0, half + t, h), grey, 0),
        scenes.Box((-0.5, -half, 0), (-0.4, half, h), grey, 0),
    ]
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    for x in (0.0, 1.0):
        for k in range(8):
            a = 2 * math.pi * k / 8
            eye, at = (x, 0.0, 0.88), (x + math.cos(a), math.sin(a), 0.88)
            frame, ids = scenes.view(boxes, eye, at, 96, 72)
            glmap.integrate(frame, scenes.semantics(ids, TEXTS))
    return glmap


def test_a_bump_that_seals_a_hall_keeps_its_contact_cell() -> None:
    """House-tune s01-006: a forward move stopped by a box below the camera's view, heading
    across a hall. The bump's segment, inflated by the body, spans the hall, so the
    marks sealed every frontier and were all forgotten; the agent drove into the box 24
    times. The contact cell alone leaves a way past it, and is kept."""
    from glmap_tools.nav.policy import _perceive_surroundings

    glmap = _hall(1.0)
    here, heading = (0.0, 0.0), math.radians(-29.0)
    bump = bump_marks(glmap, here, "move_forward", here, heading, CONFIG)
    assert not surroundings_of(glmap, here, bump.cells, CONFIG).fronts  # the case: sealed
    sur, kept = _perceive_surroundings(glmap, here, set(), bump, CONFIG)
    assert sur.fronts and kept == bump.contact
    # Older marks go first: with a sealing one from before, the fresh contact stays.
    old = {(i, 0) for i in range(20, 40)} | {(30, j) for j in range(-10, 10)}
    assert not surroundings_of(glmap, here, old, CONFIG).fronts
    sur, kept = _perceive_surroundings(glmap, here, old, bump, CONFIG)
    assert sur.fronts and kept == bump.contact
    sur, kept = _perceive_surroundings(glmap, here, old, Bump(set(), set()), CONFIG)
    assert sur.fronts and kept == set()
