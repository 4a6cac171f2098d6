"""Situations and questions as people write them, round three (issue 43): grammar-level
variants (fronted clauses, polite wrappers, options before the question, other verbs and
side words).

Its sets are held in tests/test_sqa_phrasing_sets.py."""

from glmap_tools.sqa.answer import question_type
from glmap_tools.sqa.reading import read_situation
from glmap_tools.sqa.wording import variants


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
