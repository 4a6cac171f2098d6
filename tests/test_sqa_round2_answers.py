"""The round-two question families (issue 43) answered from a hand-made map: comparisons
from distances and the units' sizes, attributes from descriptions (unsupported when they
say nothing), clock hours, sides, turning, counts on an object, divisibility, intents."""

import math

import numpy as np
import pytest

from glmap_tools.sqa.answer import OfflineAnswerer, em1, em_r1
from glmap_tools.sqa.attributes import colour_phrase
from glmap_tools.sqa.surroundings import Nearby, Surroundings, direction_of, gaussian_size


def _unit(uid, label, dist, bearing, text, size, z=(0.0, None), centre=None):
    if centre is None:
        r = dist + 0.3
        centre = (r * math.cos(math.radians(bearing)), r * math.sin(math.radians(bearing)))
    x, y = centre
    z0 = z[0]
    z1 = z[1] if z[1] is not None else z0 + size[2]
    half = max(size[0], size[1]) / 2
    foot = (x - half, y - half, x + half, y + half)
    return Nearby(uid, label, text, dist, bearing, direction_of(bearing), z0, z1, foot, size)


BED = (1.25, -2.17)
NEARBY = tuple(
    sorted(
        [
            _unit(1, "sofa", 1.0, 0.0, "a grey fabric sofa", (1.8, 0.8, 0.8)),
            _unit(2, "table", 2.0, -90.0, "a round wooden table", (1.0, 1.0, 0.75)),
            _unit(3, "lamp", 1.2, 90.0, "a floor lamp switched on", (0.3, 0.3, 1.7)),
            _unit(4, "chair", 0.8, 175.0, "a light brown chair with armrests", (0.5, 0.5, 0.9)),
            _unit(5, "chair", 1.5, -150.0, "a black and white chair", (0.5, 0.5, 0.9)),
            _unit(6, "door", 3.0, 120.0, "an open white door", (0.9, 0.1, 2.0)),
            _unit(
                7,
                "bed",
                2.2,
                -60.0,
                "a double bed with a blue cover",
                (2.0, 1.6, 0.6),
                (0, None),
                BED,
            ),
            _unit(
                8,
                "pillow",
                2.4,
                -58.0,
                "a white pillow",
                (0.5, 0.3, 0.15),
                (0.5, None),
                (1.25, -2.0),
            ),
            _unit(
                9, "pillow", 2.5, -62.0, "a grey pillow", (0.5, 0.3, 0.15), (0.5, None), (1.4, -2.3)
            ),
            _unit(10, "clock", 2.0, 30.0, "a round wall clock", (0.3, 0.05, 0.3), (2.0, None)),
            _unit(
                11, "box", 2.1, -90.0, "a cardboard box", (0.4, 0.4, 0.3), (0.0, None), (0, -2.3)
            ),
            _unit(
                12, "plant", 1.0, -35.0, "a potted plant", (0.3, 0.3, 0.8), (0, None), (1.0, -0.7)
            ),
        ],
        key=lambda n: n.distance,
    )
)
WHERE = Surroundings(0.0, 0.0, 0.0, NEARBY, (), {n.unit_id: n.label for n in NEARBY})


@pytest.mark.parametrize(
    ("question", "kind", "answer"),
    [
        ("What kind of furniture is at my two o'clock?", "clock", "bed"),
        ("Which is closer to me, the sofa or the table?", "compare", "sofa"),
        ("Is the bed bigger than the sofa?", "compare", "yes"),
        ("Which is taller, the lamp or the table?", "compare", "lamp"),
        ("Is the table farther from me than the lamp?", "compare", "yes"),
        ("Is the table round or square?", "either", "round"),
        ("Is the table a circle or a rectangle?", "either", "circle"),
        ("Is the table made of wood?", "attribute", "yes"),
        ("Is the sofa blue?", "attribute", "no"),
        ("Is the sofa leather?", "attribute", "no"),
        ("Is the shape of the clock round?", "attribute", "yes"),
        ("Does the chair behind me have armrests?", "attribute", "yes"),
        ("Is the chair behind me light brown or black and white?", "either", "light brown"),
        ("What colour is the chair behind me?", "color", "light brown"),
        ("Is the lamp on or off?", "state", "on"),
        ("Is the door open?", "state", "yes"),
        ("Is the door closed?", "state", "no"),
        ("Is the sofa in front of me or behind me?", "which_side", "front"),
        ("Is the table on my left or on my right?", "which_side", "right"),
        ("Which side of me is the lamp on?", "which_side", "left"),
        ("Do I have to look up or down to see the clock?", "up_down", "up"),
        ("Should I look up to see the clock?", "up_down", "yes"),
        ("Is the table above or below my eyes?", "up_down", "below"),
        ("How many degrees should I turn to face the chair?", "turn_angle", "180 degrees"),
        ("How many degrees do I turn to face the table?", "turn_angle", "90 degrees"),
        ("Can I see the table if I turn around?", "turn_see", "no"),
        ("If I turn to my left, can I see the door?", "turn_see", "yes"),
        ("How many pillows are on the bed?", "count_on", "2"),
        ("Number of pillows on the bed at my two o'clock?", "count_on", "2"),
        ("How many pillows on the sofa in front of me?", "count_on", "0"),
        ("How many chairs behind me?", "count", "2"),
        ("Number of chairs on my left?", "count", "0"),
        ("Is the number of chairs around me divisible by two?", "divisible", "yes"),
        ("Can the number of pillows around me be divided by three?", "divisible", "no"),
        ("If I want to leave the room, which way should I go?", "direction", "left"),
        ("I want to sleep; which direction should I go?", "direction", "right"),
        ("To reach the bed, should I turn left or right?", "direction", "right"),
        ("Where do I turn to get to the sofa?", "direction", "forward"),
        ("Which object is to my right?", "right", "table"),
        ("What is next to the bed?", "next_to", "table"),
        ("What is under the table?", "under", "box"),
        ("What is under the clock?", "under", "nothing"),
        ("What is the table made of?", "material", "wood"),
        ("What material is the sofa?", "material", "fabric"),
        ("How many chairs can I see?", "count", "0"),
        ("How many pillows are there?", "count", "2"),
        ("Where is the lamp?", "which_side", "left"),
        ("Where is the chair?", "which_side", "behind"),
        ("What is the closest object to me?", "nearest", "chair"),
        ("Is there anything on the bed?", "on_exists", "yes"),
        ("Is there anything on the sofa?", "on_exists", "no"),
        ("Is the chair within arm's reach?", "touch", "yes"),
        ("Can I open the door without getting up?", "touch", "no"),
        ("What is the table next to?", "next_to", "box"),
        ("What is between the table and the chair?", "between", "nothing"),
        ("What is between the sofa and the table?", "between", "plant"),
        ("Which one is on my left, the lamp or the table?", "which_of", "lamp"),
        ("Which is behind me, the chair or the sofa?", "which_of", "chair"),
    ],
)
def test_each_round_two_family_is_read_and_answered_from_the_map(question, kind, answer):
    a = OfflineAnswerer().answer(question, WHERE)
    assert (a.question_type, a.answer, a.supported) == (kind, answer, True), a.evidence


@pytest.mark.parametrize(
    "question",
    [
        "Is the room messy or tidy?",
        "Does the sofa have cushions?",
        "Is the bed made or messy?",
        "Is the lamp made of glass?",
    ],
)
def test_what_no_description_says_is_unsupported_not_guessed(question):
    a = OfflineAnswerer().answer(question, WHERE)
    assert (a.answer, a.supported) == ("", False) and "cannot tell" in a.evidence


def test_a_comparison_too_close_to_call_is_said_so():
    a = OfflineAnswerer().answer("Which is closer, the pillow or the bed?", WHERE)
    assert (a.question_type, a.supported) == ("compare", False)
    assert "too close to call" in a.evidence


def test_two_word_colours_keep_their_shade_and_pair():
    assert colour_phrase("a dark grey sofa") == "dark grey"
    assert colour_phrase("a black and white rug") == "black and white"
    assert colour_phrase("a teal rug") == "teal"
    assert colour_phrase("a wooden shelf") is None


def test_a_units_size_is_the_spread_of_its_gaussians_along_their_principal_axes():
    rng = np.random.default_rng(0)
    pts = rng.uniform([-1.0, -0.25, 0.0], [1.0, 0.25, 0.5], (2000, 3))
    turn = np.array([[0.6, -0.8, 0], [0.8, 0.6, 0], [0, 0, 1.0]])
    length, width, height = gaussian_size(pts @ turn.T)
    assert length == pytest.approx(2.0, abs=0.02) and width == pytest.approx(0.5, abs=0.02)
    assert height == pytest.approx(0.5, abs=0.01)


def test_degrees_and_two_word_answers_score_as_exact_matches():
    assert em1("180 degrees", ["180 degrees"]) and em1("light brown", ["Light brown"])


def test_relaxed_match_takes_front_for_forward_and_behind_for_backward_but_not_left():
    assert em_r1("forward", ["front"]) and em_r1("backward", ["behind"])
    assert not em1("forward", ["front"]) and not em_r1("forward", ["left"])


def test_a_three_letter_plural_still_names_its_label():
    from glmap_tools.sqa.answer import _match_label

    assert _match_label("tvs", ["tv", "tv stand"]) == "tv"
    assert _match_label("tvs on the stand", ["tv stand", "bus"]) is None
