"""The question families beyond 'what is on my left' (issue 32), on a hand-made scene."""

import pytest

from glmap_tools.sqa.answer import OfflineAnswerer, question_type
from glmap_tools.sqa.surroundings import Nearby, Surroundings, direction_of


def _unit(uid, label, dist, bearing, text="", centre=(0.0, 0.0)):
    x, y = centre
    return Nearby(
        uid,
        label,
        text or f"a {label}",
        dist,
        bearing,
        direction_of(bearing),
        0.0,
        1.0,
        (x - 0.3, y - 0.3, x + 0.3, y + 0.3),
    )


# Two chairs on my left (a red near one, a blue far one), one behind; a stove ahead; a
# wardrobe ahead with a lamp beside it on my left and a plant on its right; a round table.
NEARBY = (
    _unit(1, "chair", 0.6, 80.0, "a red chair", (0.0, 0.6)),
    _unit(2, "stove", 1.0, 0.0, "a white stove", (1.0, 0.0)),
    _unit(3, "chair", 1.5, 100.0, "a blue chair", (-0.3, 1.5)),
    _unit(4, "chair", 1.8, 180.0, "a grey chair", (-1.8, 0.0)),
    _unit(5, "wardrobe", 3.0, 10.0, "a tall wardrobe", (3.0, 0.5)),
    _unit(6, "lamp", 3.1, 25.0, "a lamp", (3.0, 1.3)),
    _unit(7, "plant", 3.1, -5.0, "a potted plant", (3.0, -0.3)),
    _unit(8, "table", 2.0, -90.0, "a round wooden table", (0.0, -2.0)),
    _unit(9, "refrigerator", 2.5, 60.0, "a refrigerator", (1.2, 2.2)),
)
WHERE = Surroundings(0.0, 0.0, 0.0, NEARBY, (), {n.unit_id: n.label for n in NEARBY})


@pytest.mark.parametrize(
    ("question", "kind", "answer"),
    [
        ("Which direction should I go to reach the stove?", "direction", "forward"),
        ("Which way should I turn to see the table?", "direction", "right"),
        ("Which direction is the grey chair?", "direction", "left"),
        ("Can I see the refrigerator from here?", "see", "yes"),
        ("Is the table visible from where I am?", "see", "no"),
        ("How many chairs are on my left?", "count", "2"),
        ("How many chairs are there around me?", "count", "3"),
        ("Is the number of chairs in this room even or odd?", "parity", "odd"),
        ("Is the amount of chairs on my left even or odd?", "parity", "even"),
        ("Is there another chair behind me?", "exists", "yes"),
        ("Is there a chair to my right?", "exists", "no"),
        ("Am I in the kitchen?", "in_room", "yes"),
        ("Am I in the bedroom?", "in_room", "no"),
        ("If I turn around, what is in front of me?", "turn", "chair"),
        ("If I turn to my right, what will be in front of me?", "turn", "table"),
        ("If I turn left, what is behind me?", "turn", "table"),
        ("Can I touch the red chair without getting up?", "touch", "yes"),
        ("Can I touch the stove without moving?", "touch", "no"),
        ("What colour is the chair on my left?", "color", "red"),
        ("What colour is the chair behind me?", "color", "grey"),
        ("What shape is the table?", "shape", "round"),
        ("What is on the left side of the wardrobe?", "beside", "lamp"),
        ("What is on the right side of the wardrobe?", "beside", "plant"),
        ("What's on my right-hand side?", "right", "table"),
        ("What am I facing?", "front", "stove"),
    ],
)
def test_each_family_is_read_and_answered_from_the_surroundings(question, kind, answer):
    a = OfflineAnswerer().answer(question, WHERE)
    assert (a.question_type, a.answer, a.supported) == (kind, answer, True), a.evidence


def test_what_the_map_cannot_tell_is_said_honestly_not_guessed():
    a = OfflineAnswerer().answer("Is the wardrobe open or closed?", WHERE)
    assert (a.question_type, a.supported, a.answer) == ("state", False, "")
    assert "cannot tell from the map" in a.evidence
    a = OfflineAnswerer().answer("What shape is the stove?", WHERE)
    assert not a.supported and "cannot tell" in a.evidence


def test_the_anchor_one_stands_at_is_not_counted_or_answered():
    a = OfflineAnswerer().answer("How many chairs are on my left?", WHERE, exclude=[1])
    assert a.answer == "1"


def test_the_left_side_of_an_object_is_not_read_as_on_top_of_it():
    assert question_type("What is on the left side of the wardrobe?")[0] == "beside"
    assert question_type("What is on top of the dresser?") == ("on", {"object": "dresser"})
