"""Situations and questions as people write them, round four (issue 43): a held-out set
written and committed before any rule change of this round, never tuned on. It covers the
forms the issue lists: egocentric clauses glued to the anchor, clauses inside the faced
object, activity leftovers, side/behind/clock words, texts not opening with "I", negation,
"on either side of me"; yes/no and either/or attributes, egocentric object queries,
direction intents, counts, comparisons, shape, divisibility, "if I turn around".

Measured on the code as it stood when the set was written:
before: 43 / 48 situations read right, 63 / 64 questions to their family.
After round four's rules (tuned on round three's misreads and its own tuned sentences, never
on this set): 46 / 48 situations, 63 / 64 questions. The three situations gained share
their pattern with misreads of the earlier sets ("At my back is X", ", which is on my
right", "watering the X near the Y"). Still misread: a leading "Just before going out,"
(read as the anchor), "I cannot see the fridge from where I stand at the counter" (the
negation drops the whole clause, place included), and "If I turn around, will the door be
visible?" (no family)."""

import json
from pathlib import Path

from tests.test_sqa_round2 import held_out_shares

HELD_OUT_FLOOR = {"situations": 0.95, "questions": 0.98}  # measured: 46 / 48, 63 / 64
DATA = Path(__file__).parent / "data"
HELD_OUT = json.loads((DATA / "sqa_round4_heldout.json").read_text())


def test_held_out_situations_read_right_as_measured():
    share, wrong = held_out_shares(HELD_OUT)["situations"]
    assert share >= HELD_OUT_FLOOR["situations"], wrong


def test_held_out_questions_fall_to_their_family_as_measured():
    share, wrong = held_out_shares(HELD_OUT)["questions"]
    assert share >= HELD_OUT_FLOOR["questions"], wrong


def test_round_four_shares_no_sentence_with_the_earlier_sets():
    earlier = set()
    for name in ("round2_tuned", "round2_heldout", "round3_tuned", "round3_heldout"):
        data = json.loads((DATA / f"sqa_{name}.json").read_text())
        earlier |= {c["text"] for c in data["situations"] + data["questions"]}
    held = [c["text"] for c in HELD_OUT["situations"] + HELD_OUT["questions"]]
    assert len(held) == len(set(held)) == 112 and not set(held) & earlier
