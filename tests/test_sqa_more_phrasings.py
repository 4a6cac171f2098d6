"""The phrased bench's second set of forms (sqa.more_phrasings, issue 43): same stand
points, the first set untouched, every situation text read as it was written."""

import copy

import pytest

from glmap_tools.eval.sqa_table import reading_ok
from glmap_tools.sqa.more_phrasings import HELD_OUT, QUESTION_FORMS, more_questions
from glmap_tools.worlds.qa import generate_qa, situation_phrase
from glmap_tools.worlds.splits import bench_layout, split_dir


@pytest.fixture(scope="module")
def sets():
    layout = bench_layout(split_dir("tune") / "s00" / "layout.json")
    qa = generate_qa(layout, situations=8, seed=0, phrasings=True)
    first = copy.deepcopy(qa)
    return layout, qa, first, more_questions(layout, qa, 0, situation_phrase)


def test_the_second_set_stands_where_the_first_does_and_leaves_it_as_it_was(sets):
    _, qa, first, more = sets
    assert qa == first and more
    stands = {(q["position"]["_x"], q["position"]["_y"], q["heading"]) for q in qa["questions"]}
    assert {(q["position"]["_x"], q["position"]["_y"], q["heading"]) for q in more} <= stands
    ids = [q["question_id"] for q in qa["questions"] + more]
    assert ids == list(range(len(ids)))


def test_each_record_names_its_forms_and_whether_one_is_held_out(sets):
    _, _, _, more = sets
    for q in more:
        kind, form = q["question_form"].removeprefix("r2:").split("/")
        assert q["round"] == 2 and kind == q["question_type"] and kind in QUESTION_FORMS
        held = q["situation_form"] == "r2:" + HELD_OUT[q["situation_kind"]]
        assert q["held_out"] == (held or int(form) == HELD_OUT[kind])


def test_every_second_set_situation_reads_as_it_was_written(sets):
    _, _, _, more = sets
    texts = {q["situation"]: q["reading"] for q in more}
    assert all(reading_ok(t, r) for t, r in texts.items()), texts


def test_turning_angles_are_answered_in_whole_quarter_turns(sets):
    _, _, _, more = sets
    angles = [q["answers"][0]["answer"] for q in more if q["question_type"] == "turn_angle"]
    assert angles and set(angles) <= {"0 degrees", "90 degrees", "180 degrees"}
