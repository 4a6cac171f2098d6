"""Situations told in the past tense, with a bare verb for what I do, or with what I hold:
misreadings a probe of sentences outside the phrasing sets found."""

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
