"""Situations and questions as people write them, round five: a held-out set written and
committed (da4eb60) before any rule change of this round, and a tuned set written after.

Measured on the code as it stood when the held-out set was written: 42 / 48 situations
read right, 49 / 56 questions to their family. Its misreads: a part of the anchor ("the arm
of the sofa"), what covers me ("on the sofa under a blanket"), "around the ottoman", "my
desk is at my back", "the microwave is above it", a leading time without a comma ("After my
shower I'm drying off ..."); a time tail ("open at the moment"), "in between", "my eye
level", "are there an odd or even number of", a turn asked after its question ("what will
I see if I turn around?"), "do I go left or right", a feeling before the question ("I'm
thirsty; which way ...").

The rules of this round were written against the tuned set, whose sentences are other
sentences of those kinds, so the held-out set's figure after them (48 / 48, 56 / 56) is no
longer a held-out measure: the 42 / 48 and 49 / 56 above are. The sets are held in
tests/test_sqa_phrasing_sets.py."""

import pytest

from glmap_tools.sqa.answer import OfflineAnswerer
from glmap_tools.sqa.reading import read_situation
from tests.test_sqa_round2_answers import WHERE


@pytest.mark.parametrize(
    ("question", "kind", "answer"),
    [
        ("Is the lamp to my left?", "exists", "yes"),
        ("Is the table on my left?", "exists", "no"),
        ("Is the chair behind me?", "exists", "yes"),
        ("Is the lamp on right now?", "state", "yes"),
        ("Are there an odd or even number of pillows?", "parity", "even"),
        ("What will I see if I turn around?", "turn", "chair"),
        ("What would be on my right if I turned to my left?", "turn", "sofa"),
        ("Do I go left or right to reach the bed?", "direction", "right"),
        ("Do I need to turn left or right to get to the lamp?", "direction", "left"),
        ("I'm tired; where should I go?", "direction", "right"),
        ("Is the table above or below my eye level?", "up_down", "below"),
        ("What is in between the sofa and the table?", "between", "plant"),
    ],
)
def test_the_new_wordings_are_answered_from_the_map_as_their_plain_forms(question, kind, answer):
    a = OfflineAnswerer().answer(question, WHERE)
    assert (a.question_type, a.answer, a.supported) == (kind, answer, True), a.evidence


def test_a_feeling_names_what_is_wanted_and_a_missing_one_is_said_so():
    a = OfflineAnswerer().answer("I'm hungry, which way should I go?", WHERE)
    assert (a.question_type, a.supported) == ("direction", False)
    assert "refrigerator" in a.evidence and "get something to eat" in a.evidence


@pytest.mark.parametrize(
    ("text", "anchor"),
    [
        ("I am sitting on the sofa under the window.", "sofa near the window"),  # not a cover
        ("I am standing at the desk and the lamp is on it.", "desk"),
        ("Before dinner I am standing by the stove.", "stove"),
        ("Before going to bed, I am standing at the wardrobe.", "wardrobe"),
    ],
)
def test_covers_and_things_placed_by_it_are_no_anchor_but_a_place_still_is(text, anchor):
    assert read_situation(text).anchor == anchor
