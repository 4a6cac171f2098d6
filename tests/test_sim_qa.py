"""Situated QA generation: SQA3D-like records whose answers agree with the layout."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.layout_io import layout_from_dict
from glmap_tools.sim.navgrid import build_nav_grid
from glmap_tools.worlds.generator import generate_apartment
from glmap_tools.worlds.qa import bearing, generate_qa, heading_from_rotation


@pytest.fixture(scope="module")
def layout():
    return generate_apartment(3, n_rooms=6)


@pytest.fixture(scope="module")
def qa(layout):
    return generate_qa(layout, 12, seed=0)


def _position(q: dict) -> np.ndarray:
    return np.array([q["position"]["_x"], q["position"]["_y"]])


def test_the_set_is_seeded_and_has_sqa3d_fields(layout, qa) -> None:
    assert generate_qa(layout, 12, seed=0) == qa
    assert generate_qa(layout, 12, seed=1) != qa
    q = qa["questions"][0]
    assert {"situation", "question", "answers", "position", "rotation", "scene_id"} <= set(q)
    assert q["answers"][0]["answer_id"] == 1 and q["answers"][0]["answer_confidence"] == "yes"
    assert q["situation"].startswith("I am standing ")
    assert {q["question_type"] for q in qa["questions"]} >= {"room", "color", "count", "reach"}


def test_the_rotation_quaternion_encodes_the_heading(qa) -> None:
    for q in qa["questions"]:
        assert math.isclose(math.cos(heading_from_rotation(q["rotation"]) - q["heading"]), 1.0)


def test_left_right_and_behind_answers_lie_on_that_side(layout, qa) -> None:
    sides = {"left": (45, 135), "right": (-135, -45)}
    checked = 0
    for q in qa["questions"]:
        if q["question_type"] in sides:
            obj = layout.object(q["object_ids"][-1])
            assert obj.category == q["answers"][0]["answer"]
            b = math.degrees(bearing(_position(q), heading_from_rotation(q["rotation"]), obj))
            lo, hi = sides[q["question_type"]]
            assert lo <= b <= hi
            checked += 1
    assert checked >= 3


def test_colour_count_and_room_answers_come_from_the_layout(layout, qa) -> None:
    for q in qa["questions"]:
        answer = q["answers"][0]["answer"]
        if q["question_type"] == "color":
            assert layout.object(q["object_ids"][-1]).attributes["color"] == answer
        if q["question_type"] == "count":
            assert int(q["answers"][1]["answer"]) == len(q["object_ids"]) - 2
        if q["question_type"] == "room":
            room = layout.room(layout.room_at(_position(q)))
            assert room.name == answer == q["room"]
            # A numbered room ("second bedroom") is also right by its kind alone.
            names = [a["answer"] for a in q["answers"]]
            assert names == list(dict.fromkeys([room.name, room.type]))


def test_reach_straight_ahead_is_yes_only_when_the_way_is_clear(layout, qa) -> None:
    grid = build_nav_grid(layout)
    for q in qa["questions"]:
        if q["question_type"] != "reach":
            continue
        obj = layout.object(q["object_ids"][-1])
        pos, heading = _position(q), heading_from_rotation(q["rotation"])
        if q["answers"][0]["answer"] == "yes":
            assert abs(bearing(pos, heading, obj)) < 0.35
            d = float(obj.distance_to(pos[None])[0])
            end = pos + np.array([math.cos(heading), math.sin(heading)]) * max(d - 0.6, 0.0)
            assert grid.segment_is_free(pos, end)


def test_zero_situations_are_refused(layout) -> None:
    with pytest.raises(InvalidInputError, match="situations=0"):
        generate_qa(layout, 0, seed=0)


# A kitchen with two navy cabinets against the south wall; only the west one has a neighbour
# (the refrigerator) that can single it out.
TWO_CABINETS = {
    "name": "two cabinets",
    "rooms": [
        {"id": 1, "type": "kitchen", "polygon": [[0, 0], [6, 0], [6, 5], [0, 5]]},
        {"id": 2, "type": "living room", "polygon": [[6, 0], [10, 0], [10, 5], [6, 5]]},
    ],
    "openings": [{"id": 1, "rooms": [1, 2], "center": [6, 2.5], "width": 0.9}],
    "objects": [
        {
            "id": 1,
            "category": "kitchen cabinet",
            "mesh": "kenney/kitchenCabinet",
            "position": [1.5, 0.4, 0],
            "heading": math.pi / 2,
            "attributes": {"color": "navy"},
        },
        {
            "id": 2,
            "category": "kitchen cabinet",
            "mesh": "kenney/kitchenCabinet",
            "position": [4.5, 0.4, 0],
            "heading": math.pi / 2,
            "attributes": {"color": "navy"},
        },
        {
            "id": 3,
            "category": "refrigerator",
            "mesh": "kenney/kitchenFridgeSmall",
            "position": [0.4, 0.4, 0],
            "heading": math.pi / 2,
            "attributes": {"color": "white"},
        },
        {
            "id": 4,
            "category": "table",
            "mesh": "primitive/table",
            "position": [3.0, 3.5, 0],
            "attributes": {"color": "brown"},
        },
        {
            "id": 5,
            "category": "sofa",
            "mesh": "kenney/loungeSofa",
            "position": [8.0, 4.4, 0],
            "heading": -math.pi / 2,
            "attributes": {"color": "blue"},
        },
        {
            "id": 6,
            "category": "table",
            "mesh": "primitive/table",
            "position": [8.0, 2.0, 0],
            "attributes": {"color": "brown"},
        },
    ],
}


def _fitting(layout, words: str) -> set[int]:
    """Ids of the objects `words` ("navy kitchen cabinet next to the refrigerator") fits:
    category last, attribute words among the object's, relations next to / on / in."""
    from glmap_tools.sim.instnav import NEAR, footprint_gap

    head, *rels = re.split(r" (next to|on|in) the ", words)
    fits = set()
    for o in layout.objects:
        if not head.endswith(o.category):
            continue
        if not set(head.removesuffix(o.category).split()) <= set(o.attributes.values()):
            continue
        ok = True
        for rel, obj in zip(rels[::2], rels[1::2], strict=True):
            if rel == "in":
                ok &= layout.room(o.room).name == obj
            elif rel == "on":
                ok &= o.supported_by is not None and o.supported_by in _fitting(layout, obj)
            else:
                ok &= any(
                    a.room == o.room and a.id != o.id and footprint_gap(o, a) <= NEAR
                    for a in layout.objects
                    if a.id in _fitting(layout, obj)
                )
        if ok:
            fits.add(o.id)
    return fits


def test_the_situation_names_one_anchor_and_one_facing_object_in_its_room() -> None:
    layout = layout_from_dict(TWO_CABINETS)
    qa = generate_qa(layout, 30, seed=0)
    assert qa["version"] == 3
    seen = {}
    for q in qa["questions"]:
        m = re.fullmatch(
            r"I am standing (?:at|next to) the (.+), facing the (.+)\.", q["situation"]
        )
        assert m, q["situation"]
        anchor, facing = q["object_ids"][:2]
        assert _fitting(layout, m[1]) == {anchor}, q["situation"]
        room = layout.object(anchor).room
        assert {i for i in _fitting(layout, m[2]) if layout.object(i).room == room} == {facing}
        seen[anchor] = m[1]
    # The west cabinet is named by its neighbour; the east one, which nothing singles out,
    # is never an anchor.
    assert seen.get(1) == "navy kitchen cabinet next to the white refrigerator", seen
    assert 2 not in seen


@pytest.fixture(scope="module")
def phrased(layout):
    return generate_qa(layout, 12, seed=0, phrasings=True)


def test_phrasings_keep_the_poses_and_plain_answers_and_vary_the_words(qa, phrased) -> None:
    from glmap_tools.worlds.qa_phrasings import QUESTION_FORMS, SITUATION_FORMS

    plain = {(q["position"]["_x"], q["position"]["_y"], q["heading"]) for q in qa["questions"]}
    poses = {(q["position"]["_x"], q["position"]["_y"], q["heading"]) for q in phrased["questions"]}
    assert poses == plain
    assert sum(len(f) for f in SITUATION_FORMS.values()) >= 8
    assert sum(len(f) for f in QUESTION_FORMS.values()) >= 20
    assert len({q["situation_form"] for q in phrased["questions"]}) >= 5
    assert {q["question_type"] for q in phrased["questions"]} >= {"direction", "parity", "in_room"}
    assert any(q["held_out"] for q in phrased["questions"])
    assert not all(q["held_out"] for q in phrased["questions"])


def test_every_phrased_question_is_read_as_its_family_and_every_situation_as_written(
    phrased,
) -> None:
    from glmap_tools.eval.sqa_table import reading_ok
    from glmap_tools.sqa.answer import question_type

    for q in phrased["questions"]:
        assert question_type(q["question"])[0] == q["question_type"], q["question"]
        assert reading_ok(q["situation"], q["reading"]), (q["situation"], q["reading"])


def test_direction_and_turn_answers_agree_with_the_true_pose(layout, phrased) -> None:
    for q in phrased["questions"]:
        if q["question_type"] not in ("direction", "turn"):
            continue
        obj = layout.object(q["object_ids"][2])
        b = math.degrees(bearing(_position(q), q["heading"], obj))
        if q["question_type"] == "turn":
            assert abs(b) >= 150.0
        else:
            want = {"forward": abs(b) < 45, "backward": abs(b) > 135, "left": 45 <= b <= 135}
            assert want.get(q["answers"][0]["answer"], -135 <= b <= -45), (q["question"], b)


def test_glmap_sim_qa_writes_the_phrased_set_on_request(layout, phrased, tmp_path) -> None:
    import json

    from glmap_tools import cli
    from glmap_tools.sim.layout_io import save_layout

    save_layout(layout, tmp_path / "layout.json")
    out = tmp_path / "qa.json"
    assert cli.main(["sim", "qa", str(tmp_path / "layout.json"), "--situations", "12",
                     "--phrasings", "--out", str(out)]) == 0  # fmt: skip
    written = json.loads(out.read_text())["questions"]
    assert [q["situation"] for q in written] == [q["situation"] for q in phrased["questions"]]
    assert all("situation_form" in q and "held_out" in q for q in written)
