"""Reading situation texts into position, facing and egocentric constraints (issue 32)."""

import json
from pathlib import Path

import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sqa.reading import Constraint, SituationReading, read_situation
from glmap_tools.sqa.relations import relation_phrases

REAL = json.loads((Path(__file__).parent / "data" / "sqa_real_situations.json").read_text())


def _summary(r):
    cons = [[c.object, c.side or c.clock] for c in r.constraints]
    return relation_phrases(r.anchor)[0], r.facing, cons


@pytest.mark.parametrize("case", REAL["situations"], ids=lambda c: c["text"][:40])
def test_each_real_style_situation_reads_to_the_anchor_facing_and_constraints_a_person_sees(
    case,
):
    r = read_situation(case["text"])
    assert _summary(r) == (case["anchor"], case["facing"], case["constraints"]), r.as_dict()


def test_the_twenty_real_style_situations_are_twenty_distinct_texts():
    texts = [c["text"] for c in REAL["situations"]]
    assert len(texts) == len(set(texts)) == 20


def test_an_activity_at_a_place_anchors_on_the_place_and_keeps_the_activity():
    r = read_situation("I am rinsing a cup at the kitchen sink.")
    assert (r.anchor, r.relation, r.activity) == ("kitchen sink", "at", "rinsing a cup")
    r = read_situation("I am closing the curtains.")
    assert (r.anchor, r.activity) == ("curtains", "closing the curtains")


def test_in_front_of_is_one_relation_not_in_followed_by_front():
    r = read_situation("I am standing in front of the stove.")
    assert (r.anchor, r.relation, r.posture) == ("stove", "in front of", "standing")


def test_my_back_is_facing_is_a_constraint_behind_not_a_facing_object():
    r = read_situation("I am sitting on the sofa and my back is facing the window.")
    assert r.facing is None
    assert r.constraints == (Constraint("window", side="behind"),)


def test_x_facing_y_in_front_of_me_keeps_the_anchor_out_of_the_facing_phrase():
    r = read_situation("I am sitting at the desk, the monitor in front of me.")
    assert (r.anchor, r.facing) == ("desk", "monitor")


def test_clock_directions_become_bearings_twelve_ahead_and_three_to_the_right():
    r = read_situation("I am at the bed. The lamp is in my 2 o'clock direction.")
    (c,) = r.constraints
    assert (c.clock, c.bearing_deg) == (2, -60.0)
    assert Constraint("x", clock=9).bearing_deg == 90.0
    assert Constraint("x", clock=6).bearing_deg == 180.0
    assert read_situation("At my twelve o'clock is the tv.").facing == "tv"


@pytest.mark.parametrize(
    "text",
    [
        "The door is on my left.",
        "To my left is the door.",
        "I have the door to my left.",
        "On my left-hand side there is a door.",
        "my left is the door",
    ],
)
def test_the_phrasings_of_an_object_on_my_left_all_read_the_same(text):
    assert read_situation(text).constraints == (Constraint("door", side="left"),)


def test_a_reading_round_trips_through_its_json_form_and_bad_forms_are_refused():
    r = read_situation("I am facing a bookshelf, and a lamp is on my right.")
    assert SituationReading.from_dict(r.as_dict()) == r
    with pytest.raises(InvalidInputError, match="exactly one"):
        Constraint("lamp")
    with pytest.raises(InvalidInputError, match="1..12"):
        Constraint("lamp", clock=13)
    with pytest.raises(InvalidInputError, match="unknown"):
        SituationReading.from_dict({"anchr": "bed"})
    with pytest.raises(InvalidInputError, match="empty"):
        read_situation("  ")


@pytest.mark.parametrize(
    ("text", "anchor", "facing", "constraints"),
    [
        ("I am sitting on the couch facing the tv in front of me.", "couch", "tv", []),
        (
            "I am standing at the window looking outside, the bed is at my 5 o clock.",
            "window",
            None,
            [["bed", 5]],
        ),
        (
            "I am seated on the toilet and the sink is to my right.",
            "toilet",
            None,
            [["sink", "right"]],
        ),
        ("The desk is on my left while I am lying on the bed.", "bed", None, [["desk", "left"]]),
        (
            "I am standing by the floor lamp with a green shade and to my right is the plant.",
            "floor lamp with a green shade",
            None,
            [["plant", "right"]],
        ),
        (
            "I am standing at the stove, facing the cabinet next to the fridge.",
            "stove",
            "cabinet next to the fridge",
            [],
        ),
    ],
)
def test_clauses_that_once_swallowed_the_anchor_or_the_facing_object_read_apart(
    text, anchor, facing, constraints
):
    r = read_situation(text)
    assert (r.anchor, r.facing, [[c.object, c.side or c.clock] for c in r.constraints]) == (
        anchor,
        facing,
        constraints,
    ), r.as_dict()
