"""Situations and questions as people write them, round six: a held-out set written after
round five's rules and committed before any change of this round, and a tuned set after.

Measured on the code as it stood when the held-out set was written: 16 / 28 situations
read right, 26 / 30 questions to their family. Its misreads: a part of the anchor ("the end
of the couch", "the left side of the sofa", "the top of the stairs", "to the right of the
bed"), an anchor placed by words the locator does not read ("against the wall", "across
from the bed", "opposite the sofa", "above the sink"), "there is a X ... I am sitting on
it", "doing the dishes" after the place, "looking up at", "on the floor next to the X"; a
participle in "is there anything lying on", "could I reach", "is the number of X even?",
"where should I go" after an intent.

As in round five, the held-out set's figure after this round's rules (28 / 28, 30 / 30) is
no longer a held-out measure: the 16 / 28 and 26 / 30 above are. The sets are held in
tests/test_sqa_phrasing_sets.py."""

import pytest

from glmap_tools.sqa.answer import OfflineAnswerer
from glmap_tools.sqa.reading import read_situation
from tests.test_sqa_round2_answers import WHERE


@pytest.mark.parametrize(
    ("question", "kind", "answer"),
    [
        ("Is the number of pillows odd?", "parity", "no"),
        ("Is the number of pillows even?", "parity", "yes"),
        ("Could I touch the chair without getting up?", "touch", "yes"),
        ("If I want to sleep, where should I go?", "direction", "right"),
        ("Is there anything lying on the bed?", "on_exists", "yes"),
        ("Is there something placed on the sofa?", "on_exists", "no"),
    ],
)
def test_the_new_wordings_are_answered_from_the_map(question, kind, answer):
    a = OfflineAnswerer().answer(question, WHERE)
    assert (a.question_type, a.answer, a.supported) == (kind, answer, True), a.evidence


@pytest.mark.parametrize(
    ("text", "anchor", "relation"),
    [
        ("There is a sofa against the wall and I am sitting on it.", "sofa near the wall", "on"),
        (
            "There are two chairs by the table and I sit on one of them.",
            "chairs next to the table",
            "on",
        ),
        ("There is a lamp in the corner.", "", ""),  # says nothing of where I am
        ("I am on the floor next to the bed.", "bed", "next to"),
        ("I am sitting on the floor.", "floor", "on"),  # the floor alone is still the place
        (
            "I am standing on the rug in front of the fireplace.",
            "rug near the fireplace",
            "on",
        ),
        ("I am standing to the left of the fridge.", "fridge", "to"),
    ],
)
def test_a_thing_brought_in_by_there_is_is_what_it_names_and_the_floor_no_place(
    text, anchor, relation
):
    r = read_situation(text)
    assert (r.anchor, r.relation) == (anchor, relation)


def test_a_there_is_clause_that_places_the_thing_around_me_stays_a_constraint():
    r = read_situation("There is a clock at two o'clock and I am sitting on the bed.")
    assert (r.anchor, [(c.object, c.clock) for c in r.constraints]) == ("bed", [("clock", 2)])
