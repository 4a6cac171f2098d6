"""InstNav on scans without descriptions (issue 40): a unit is only its category, so
"the table next to the chair" is matched by category + relation, not by a sentence score
that stays under the InstNav threshold."""

from __future__ import annotations

import math

import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav import NavConfig
from glmap_tools.nav.perceive import NEXT_TO, RelationalGoal, relational_goal
from glmap_tools.nav.policy import NavState, decide
from glmap_tools.sim import instnav
from glmap_tools.sim.instnav import describe_instance
from glmap_tools.sim.layout_io import layout_from_dict

# A dining corner of our own, as a scan gives it: categories only, no descriptions.
TEXTS = {1: ("chair", "chair"), 2: ("table", "table"), 3: ("table", "table")}
NEAR_TABLE, FAR_TABLE = (1.2, 0.2), (-1.5, -1.5)


@pytest.fixture(scope="module")
def scanned() -> GLMap:
    boxes = scenes.floor(6.0) + scenes.chair(1.2, 1.3, object_id=1)
    boxes += scenes.table(*NEAR_TABLE, object_id=2) + scenes.table(*FAR_TABLE, object_id=3)
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    for k in range(16):  # twice round, so every unit is seen in two frames
        a = 2 * math.pi * k / 8
        frame, ids = scenes.view(boxes, (0, 0, 0.88), (math.cos(a), math.sin(a), 0.6), 160, 120)
        glmap.integrate(frame, scenes.semantics(ids, TEXTS))
    return glmap


def _table_near(glmap: GLMap, xy: tuple[float, float]) -> int:
    tables = [u for u in glmap.instances.values() if u.label == "table"]
    return min(tables, key=lambda u: math.dist(u.centroid[:2], xy)).id


def test_the_goal_is_read_as_category_and_relation() -> None:
    assert relational_goal("the table next to the chair") == RelationalGoal(
        "table", "next to", "chair"
    )
    assert relational_goal("The lamp on the nightstand in the bedroom") == RelationalGoal(
        "lamp", "on", "nightstand"
    )
    assert relational_goal("the chair in the kitchen") == RelationalGoal("chair", "in", "kitchen")
    assert relational_goal("sofa") is None
    assert NEXT_TO == instnav.NEAR


def test_the_simulator_s_descriptions_of_a_scan_without_attributes_read_back() -> None:
    box = {"mesh": "primitive/box"}
    objects = [
        {"id": 1, "category": "chair", "position": [4.2, 2.8, 0], "size": [0.45, 0.5, 0.9]},
        {"id": 2, "category": "table", "position": [4.2, 1.7, 0], "size": [1.2, 0.8, 0.75]},
        {"id": 3, "category": "table", "position": [1.0, 1.0, 0], "size": [1.2, 0.8, 0.75]},
    ]
    room = {"id": 1, "type": "dining room", "polygon": [[0, 0], [6, 0], [6, 5], [0, 5]]}
    layout = layout_from_dict(
        {"name": "corner", "rooms": [room], "objects": [{**box, **o} for o in objects]}
    )
    text = describe_instance(layout, layout.object(2))
    assert text == "the table next to the chair"
    assert relational_goal(text) == RelationalGoal("table", "next to", "chair")


def test_a_unit_of_the_category_next_to_the_anchor_matches_the_instnav_goal(scanned) -> None:
    near, far = _table_near(scanned, NEAR_TABLE), _table_near(scanned, FAR_TABLE)
    assert near != far
    config = NavConfig.for_task("instnav", initial_spin=0)
    state = NavState()
    goal = "the table next to the chair"
    d = decide(scanned, (0.0, 0.0), 0.0, goal, config=config, state=state)
    assert d.scores[near] < config.stop_threshold  # the sentence alone does not reach it
    assert d.matched_unit == near, d.waypoint.reason
    assert d.waypoint.kind == "goal"
    # "on" asks the footprints to overlap: the table does not stand on the chair.
    assert (
        decide(scanned, (0.0, 0.0), 0.0, "the table on the chair", config=config).matched_unit
        is None
    )


def test_a_goal_whose_anchor_is_not_near_any_unit_matches_nothing(scanned) -> None:
    config = NavConfig.for_task("instnav", initial_spin=0)
    d = decide(scanned, (0.0, 0.0), 0.0, "the chair next to the sofa", config=config)
    assert d.matched_unit is None


def test_in_the_room_matches_only_a_category_the_map_holds_once(scanned) -> None:
    config = NavConfig.for_task("instnav", initial_spin=0)
    chair = next(u.id for u in scanned.instances.values() if u.label == "chair")
    d = decide(scanned, (0.0, 0.0), 0.0, "the chair in the dining room", config=config)
    assert d.matched_unit == chair
    two = decide(scanned, (0.0, 0.0), 0.0, "the table in the dining room", config=config)
    assert two.matched_unit is None  # two tables: the room cannot tell them apart here
