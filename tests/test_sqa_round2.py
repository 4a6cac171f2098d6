"""Situations as people write them, round two (issue 43): what the round's rules read (its
sets are held in tests/test_sqa_phrasing_sets.py)."""

from glmap_tools.sqa.reading import Constraint, read_situation


def test_an_egocentric_clause_on_the_anchor_is_a_constraint_not_part_of_its_name():
    r = read_situation("I am waiting by the heater which is on my left.")
    assert (r.anchor, r.constraints) == ("heater", (Constraint("heater", side="left"),))


def test_a_negated_clause_gives_no_place_and_no_facing():
    r = read_situation("I don't see the oven; I am sitting on the stool.")
    assert (r.anchor, r.facing, r.constraints) == ("stool", None, ())


def test_on_either_side_of_me_puts_one_on_my_left_and_one_on_my_right():
    r = read_situation("I am lying on the bed with a lamp on either side of me.")
    assert r.constraints == (Constraint("lamp", side="left"), Constraint("lamp", side="right"))


def test_a_leading_adverbial_clause_is_not_the_anchor():
    r = read_situation("Once inside, I sat down on the sofa facing the tv.")
    assert (r.anchor, r.facing) == ("sofa", "tv")
