"""Situations told in the past tense, with a bare verb for what I do, with what I hold, or
with "it" after two things: misreadings a probe of sentences outside the phrasing sets
found."""

import pytest

from glmap_tools.sqa.reading import read_situation
from tests.test_sqa_phrasing_sets import summary


@pytest.mark.parametrize(
    ("text", "reading"),
    [
        (
            "I was sitting on the bed and the window was to my left.",
            ("bed", None, [["window", "left"]]),
        ),
        ("While I was cooking, the fridge was behind me.", ("", None, [["fridge", "behind"]])),
        ("I sat on the sofa and the tv was in front of me.", ("sofa", "tv", [])),
        ("We were standing at the door.", ("door", None, [])),
        ("I was at the desk, and the lamp was at my 2 o'clock.", ("desk", None, [["lamp", 2]])),
    ],
)
def test_a_situation_told_in_the_past_reads_as_the_present(text, reading):
    assert summary(read_situation(text)) == reading


@pytest.mark.parametrize(
    "text",
    [
        "While I cook, the fridge is behind me.",
        "The fridge is behind me while I cook.",
        "I cook and the fridge is behind me.",
    ],
)
def test_a_verb_alone_is_what_i_do_not_where_i_am(text):
    r = read_situation(text)
    assert (r.anchor, r.activity) == ("", "cook")
    assert summary(r)[2] == [["fridge", "behind"]]


@pytest.mark.parametrize(
    ("text", "anchor"),
    [
        ("I'm standing at the counter with a cup in my hand.", "counter"),
        ("I'm sitting on the couch with a book in my lap.", "couch"),
        ("I stood by the window with my phone in my hands.", "window"),
    ],
)
def test_what_i_hold_is_no_part_of_the_place(text, anchor):
    assert read_situation(text).anchor == anchor


@pytest.mark.parametrize(
    ("text", "anchor"),
    [
        ("The lamp is next to the sofa, and I am sitting on it.", "sofa"),
        ("The cat is on the bed and I'm lying on it.", "bed"),
        ("The tv is across from the couch and I'm sitting on it.", "couch"),
        ("There is a sofa against the wall and I am sitting on it.", "sofa"),
        ("A cushion is on the chair and I am sitting on it.", "cushion"),  # both hold me
        ("The plant is by the window and I'm standing next to it.", "plant"),  # no seat asked
        ("The lamp by the bed is next to the chair and I'm sitting on it.", "chair"),
    ],
)
def test_it_that_i_sit_or_lie_on_is_the_seat_of_the_two_things_just_named(text, anchor):
    assert summary(read_situation(text))[0] == anchor  # the anchor's object words


@pytest.mark.parametrize(
    ("text", "anchor"),
    [
        ("I'm perched on the sofa's arm with the lamp on my left.", "sofa"),
        ("I'm at the table's far end.", "table"),
        ("I'm lying on the couch with a blanket over it.", "couch"),
        ("I'm sitting at the table with the chairs around it.", "table"),
        ("I am standing at the counter with the sink next to it, facing the window.", "counter"),
    ],
)
def test_a_part_owned_by_the_place_and_what_stands_by_it_are_the_place(text, anchor):
    assert summary(read_situation(text))[0] == anchor
