"""Situations and questions as people write them, round three (issue 43): grammar-level
variants (fronted clauses, polite wrappers, options before the question, other verbs and
side words). The tuned phrasings read right one by one.

The "held-out" set was written and committed before round three's rules changed and read
35 / 42 situations and 71 / 72 questions right then. Round four tuned on its misreads, so
it is a tuned set from here on (round four's held-out set is tests/test_sqa_round4.py):
now 42 / 42 and 72 / 72, held whole."""

import json
from pathlib import Path

import pytest

from glmap_tools.sqa.answer import question_type
from glmap_tools.sqa.reading import read_situation
from glmap_tools.sqa.wording import variants
from tests.test_sqa_round2 import _summary, held_out_shares

HELD_OUT_FLOOR = {"situations": 1.0, "questions": 1.0}  # tuned on since round four
DATA = Path(__file__).parent / "data"
TUNED = json.loads((DATA / "sqa_round3_tuned.json").read_text())
HELD_OUT = json.loads((DATA / "sqa_round3_heldout.json").read_text())


@pytest.mark.parametrize("case", TUNED["situations"], ids=lambda c: c["text"][:40])
def test_each_tuned_situation_reads_to_its_anchor_facing_and_constraints(case):
    r = read_situation(case["text"])
    assert _summary(r) == (case["anchor"], case["facing"], case["constraints"]), r.as_dict()


@pytest.mark.parametrize("case", TUNED["questions"], ids=lambda c: c["text"][:40])
def test_each_tuned_question_falls_to_its_family(case):
    assert question_type(case["text"])[0] == case["family"]


def test_held_out_situations_read_right_as_measured():
    share, wrong = held_out_shares(HELD_OUT)["situations"]
    assert share >= HELD_OUT_FLOOR["situations"], wrong


def test_held_out_questions_fall_to_their_family_as_measured():
    share, wrong = held_out_shares(HELD_OUT)["questions"]
    assert share >= HELD_OUT_FLOOR["questions"], wrong


def test_round_three_shares_no_sentence_with_the_earlier_sets():
    earlier = set()
    for name in ("sqa_round2_tuned.json", "sqa_round2_heldout.json"):
        data = json.loads((DATA / name).read_text())
        earlier |= {c["text"] for c in data["situations"] + data["questions"]}
    tuned = {c["text"] for c in TUNED["situations"] + TUNED["questions"]}
    held = {c["text"] for c in HELD_OUT["situations"] + HELD_OUT["questions"]}
    assert not (tuned | held) & earlier and not tuned & held


def test_a_question_as_written_wins_over_its_other_wordings():
    assert question_type("What is on my left?") == ("left", {})


def test_options_before_the_question_go_to_its_end():
    assert "which one is closer to me, the bed or the desk?" in variants(
        "of the bed and the desk, which one is closer to me"
    )
    kind, parts = question_type("Among the fridge and the oven, which is further away?")
    assert (kind, parts["a"], parts["b"], parts["rel"]) == ("compare", "fridge", "oven", "further")


def test_a_polite_wrapper_and_an_embedded_question_are_read_as_the_question():
    assert question_type("Could you tell me if the fridge is open?") == (
        "state",
        {"object": "fridge", "value": "open"},
    )


def test_a_fronted_place_is_the_place_asked():
    assert question_type("At my ten o'clock, which object do I see?") == ("clock", {"hour": "ten"})


def test_towards_my_left_is_my_left():
    r = read_situation("Towards my left I see the shower, while I am drying my hair at the mirror.")
    assert (r.facing, [(c.object, c.side) for c in r.constraints]) == (None, [("shower", "left")])


def test_the_anchors_own_relation_stays_in_words_the_locator_reads():
    r = read_situation("I'm perched on a stool at the kitchen island, facing the oven.")
    assert (r.anchor, r.facing) == ("stool next to the kitchen island", "oven")
    r = read_situation("I am sitting on the rug between the sofa and the fireplace.")
    assert r.anchor == "rug near the sofa near the fireplace"


def test_a_comma_set_which_clause_gives_the_object_before_it_its_side():
    r = read_situation("I am drying dishes by the dishwasher, which is to my left.")
    assert (r.anchor, [(c.object, c.side) for c in r.constraints]) == (
        "dishwasher",
        [("dishwasher", "left")],
    )


def test_an_object_worked_on_in_place_is_the_anchor_not_what_it_is_near():
    assert read_situation("I am watering the plant near the window.").anchor == (
        "plant near the window"
    )
    assert read_situation("I am feeding the cat next to the fridge.").anchor == "fridge"


def test_a_simple_present_verb_with_its_object_leaves_the_place_as_anchor():
    r = read_situation("I wash dishes at the sink.")
    assert (r.anchor, r.activity) == ("sink", "wash dishes")
