"""Situations and questions as people write them: every set in tests/data/sqa_round*.json.

A tuned set is what rules were written against: each of its sentences reads right. A held-out
set was written and committed before the rules of its round changed and is held to a floor;
its figure when written (below) is the one for text the reader had not met. Once rules are
written after its misreads were seen, its floor rises to what it reads and it says no more
about unseen text. docs/evaluation.md has the table.

- round2_heldout: 0.9 each since round two.
- round3_heldout: 35 / 42 situations and 71 / 72 questions when written; round four tuned on
  its misreads.
- round4_heldout: 43 / 48 and 63 / 64 when written; 46 / 48 and 63 / 64 after round four's
  rules (tuned on round three's misreads and its own tuned sentences). Still misread: a
  leading "Just before going out,", "I cannot see the fridge from where I stand at the
  counter" (the negation drops the place too), "If I turn around, will the door be visible?".
- round5_heldout: 42 / 48 and 49 / 56 when written (tests/test_sqa_round5.py lists its kinds
  of misread); whole after round five's rules.
- round6_heldout: 16 / 28 and 26 / 30 when written (tests/test_sqa_round6.py); whole after
  round six's rules.
- round7_heldout: 22 / 24 and 22 / 24 when written after round six's rules; whole after
  round eight's rules (tests/test_sqa_round8.py). Its misreads were: "the lamp's on my
  right" (the object kept its "'s"), "resting my elbows on the windowsill" (the elbows
  taken for the place), "which way to the front door?" (no verb), "could I see the window
  if I turned to the right?" (read as plain seeing).
- round8_heldout: 25 / 30 and 27 / 30 when written after round six's rules; whole after
  round eight's rules. Its misreads were: "the towel is hanging to my right" (the
  participle kept with the object), a leading "While the kettle boils," (the conjunction
  split off first), "the stool in front of the kitchen island" and "the chair to the left
  of the fireplace" (relations the locator does not read kept in the name), "putting on my
  shoes by the front door" (the shoes taken for the place); "what is the material of the
  floor?", "what's the object at my two o'clock?", "is the shelf above me?".
- round9_heldout: 31 / 35 and 35 / 36 when written after round eight's rules; 34 / 35 and
  36 / 36 after round nine's (tests/test_sqa_round9.py). Its misreads were: "at the kitchen
  counter on a bar stool" (the stool kept in the counter's name), "pulling a book off the
  shelf" (the book taken for the place), "there is a rug under my feet and I'm standing at
  the window" (the rug taken for the place), "looking at the mirror on the wall" (read as
  the mirror, where the set says "mirror on the wall", still so); "which object is closest
  to where I am?".
- round10_heldout: 28 / 30 and 36 / 36 when written after round nine's rules. Misread: "on
  the bed's edge" (the possessive part kept as the name) and "at the window with the
  radiator under it" (the clause about the radiator kept in the window's name); whole after
  the rules of tests/test_sqa_past_and_held.py, written against other sentences of both kinds.
- round11_heldout: 29 / 31 and 25 / 32 when written after round ten's rules and the past
  tense's. Misread: "the fridge is over to my left" ("is over" kept with the object), "I
  have just walked in and I'm standing at ..." (the entry taken for the place); "what's
  sitting off to my right?", "what object is at 3 o'clock from me?", "are the curtains
  drawn?", "what's sitting on top of the dresser?", "is anything on the nightstand?",
  "where's the bin relative to me?", "is the clock above my eye level or below it?".
  31 / 31 and 31 / 32 after round eleven's rules (tests/test_sqa_round11.py); "where's the
  bin relative to me?" stays "direction", the family that rule reads "where is X relative to
  me" as on purpose (both answer with a side).
- round12_heldout: 24 / 30 and 30 / 32 when written after round eleven's rules and those of
  tests/test_sqa_past_and_held.py. Misread: "cross-legged on the yoga mat" and "stretched out
  on the sofa" (the manner taken for the place), "working on my laptop at the kitchen table"
  (the laptop), "in the doorway with the bed straight ahead" (the bed kept with the
  doorway), "my chair is pushed back from the desk and I'm sitting in it" ("it" unread), a
  run-on "at the stove cooking pasta the fridge is on my right"; "what's right behind my
  back?", "how many cushions can I spot?". Whole after round twelve's rules
  (tests/test_sqa_round12.py).
- round13_heldout: 25 / 30 and 27 / 31 when written after round twelve's rules, not tuned on:
  the figure for the reader as it stands (one label was set to the sets' convention after
  the first reading: a thing at my 12 o'clock is what I face). Misread: a leading "ok so",
  "Me: on the couch (facing the tv)", a leading "At the moment", "the lid of the toilet",
  "the kitchen floor next to the dishwasher"; "whats on my left" (no apostrophe), "what's
  that thing at 2 o'clock?", "is there an even number of cushions?", "is the number of lamps
  a multiple of 3?".
"""

import json
from pathlib import Path

import pytest

from glmap_tools.sqa.answer import question_type
from glmap_tools.sqa.reading import read_situation
from glmap_tools.sqa.relations import relation_phrases

DATA = Path(__file__).parent / "data"
TUNED = (
    "round2_tuned", "round3_tuned", "round5_tuned", "round6_tuned", "round8_tuned",
    "round9_tuned", "round11_tuned", "round12_tuned",
)  # fmt: skip
# held-out set: (situations, questions) floor of the share read right
HELD_OUT = {
    "round2_heldout": (0.9, 0.9),
    "round3_heldout": (1.0, 1.0),
    "round4_heldout": (0.95, 0.98),
    "round5_heldout": (1.0, 1.0),
    "round6_heldout": (1.0, 1.0),
    "round7_heldout": (1.0, 1.0),
    "round8_heldout": (1.0, 1.0),
    "round9_heldout": (0.97, 1.0),
    "round10_heldout": (1.0, 1.0),
    "round11_heldout": (1.0, 0.96),
    "round12_heldout": (1.0, 1.0),
    "round13_heldout": (0.83, 0.87),
}
SIZES = {  # sentences per set (situations + questions)
    "round2_tuned": 102, "round2_heldout": 79, "round3_tuned": 80, "round3_heldout": 114,
    "round4_heldout": 112, "round5_heldout": 104, "round5_tuned": 30, "round6_heldout": 58,
    "round6_tuned": 22, "round7_heldout": 48, "round8_heldout": 60, "round8_tuned": 19,
    "round9_heldout": 71, "round9_tuned": 8, "round10_heldout": 66, "round11_heldout": 63,
    "round11_tuned": 19, "round12_heldout": 62, "round12_tuned": 8,
    "round13_heldout": 61,
}  # fmt: skip


def load(name: str) -> dict:  # type: ignore[type-arg]
    return json.loads((DATA / f"sqa_{name}.json").read_text())


def summary(r):  # type: ignore[no-untyped-def]
    """(the anchor's object words, facing, [[object, side or clock hour]]) of a reading."""
    cons = [[c.object, c.side or c.clock] for c in r.constraints]
    return relation_phrases(r.anchor)[0], r.facing, cons


def read_right(case: dict) -> bool:  # type: ignore[type-arg]
    return summary(read_situation(case["text"])) == (
        case["anchor"],
        case["facing"],
        case["constraints"],
    )


def held_out_shares(data: dict) -> dict:  # type: ignore[type-arg]
    """{situations, questions}: (share read right / to their family, the texts that miss)."""
    right = [read_right(c) for c in data["situations"]]
    family = [question_type(q["text"])[0] == q["family"] for q in data["questions"]]
    return {
        kind: (sum(ok) / len(ok), [c["text"] for c, v in zip(data[kind], ok, strict=True) if not v])
        for kind, ok in (("situations", right), ("questions", family))
    }


def _cases(kind: str) -> list:  # type: ignore[type-arg]
    return [
        pytest.param(c, id=f"{name}: {c['text'][:40]}") for name in TUNED for c in load(name)[kind]
    ]


@pytest.mark.parametrize("case", _cases("situations"))
def test_each_tuned_situation_reads_to_its_anchor_facing_and_constraints(case):
    r = read_situation(case["text"])
    assert summary(r) == (case["anchor"], case["facing"], case["constraints"]), r.as_dict()


@pytest.mark.parametrize("case", _cases("questions"))
def test_each_tuned_question_falls_to_its_family(case):
    assert question_type(case["text"])[0] == case["family"]


@pytest.mark.parametrize("name", HELD_OUT)
def test_each_held_out_set_reads_at_least_its_floor(name):
    shares = held_out_shares(load(name))
    for kind, floor in zip(("situations", "questions"), HELD_OUT[name], strict=True):
        share, wrong = shares[kind]
        assert share >= floor, (kind, wrong)


def test_no_sentence_is_in_two_sets_and_every_set_is_counted():
    names = sorted(p.stem.removeprefix("sqa_") for p in DATA.glob("sqa_round*.json"))
    assert names == sorted(SIZES) == sorted((*TUNED, *HELD_OUT))
    texts = {n: [c["text"] for c in load(n)["situations"] + load(n)["questions"]] for n in names}
    assert {n: len(t) for n, t in texts.items()} == SIZES
    every = [t for n in names for t in texts[n]]
    assert len(every) == len(set(every))
