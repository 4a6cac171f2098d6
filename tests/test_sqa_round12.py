"""Situations and questions as people write them, round twelve: rules written against a tuned
set after round twelve's held-out misreads (24 / 30 and 30 / 32 when written) were seen. The
sets are held in tests/test_sqa_phrasing_sets.py."""

import pytest

from glmap_tools.sqa.reading import read_situation
from tests.test_sqa_phrasing_sets import summary
from tests.test_sqa_round11 import assert_answered_as


@pytest.mark.parametrize(
    ("text", "reading"),
    [
        (
            "I'm curled up on the armchair, the lamp to my right.",
            ("armchair", None, [["lamp", "right"]]),
        ),
        ("I'm reading on my tablet at the dining table.", ("dining table", None, [])),
        ("I'm in the kitchen with the fridge right ahead.", ("kitchen", "fridge", [])),
        ("My bench is pulled out from the table and I'm sitting on it.", ("bench", None, [])),
        (
            "i am at the desk typing an email the printer is on my left",
            ("desk", None, [["printer", "left"]]),
        ),
        ("I am standing by the door that is on my right.", ("door", None, [["door", "right"]])),
    ],
)
def test_a_manner_what_is_mine_what_lies_ahead_and_a_run_on_read_as_where_i_am(text, reading):
    assert summary(read_situation(text)) == reading


@pytest.mark.parametrize(
    ("question", "plain"),
    [
        ("What is behind my back?", "What is behind me?"),
        ("How many chairs can I spot?", "How many chairs can I see?"),
    ],
)
def test_a_question_worded_another_way_gets_the_plain_questions_answer(question, plain):
    assert_answered_as(question, plain)
