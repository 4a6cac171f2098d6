"""glmap eval sqa on a small split: the table, resuming, and bad settings."""

import json

import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.eval.sqa import SQA_AGENTS, SqaSpec, check_agents, run_sqa_eval

SMALL = SqaSpec(
    split="tune",
    scenes=1,
    situations=3,
    embedder="hashing",
    image=(160, 120),
    tour_step=1.0,
    tour_spin=4,
)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sqa")
    text, records = run_sqa_eval(SMALL, out, workers=1, progress=False)
    return out, text, records


def test_a_small_split_prints_em_for_every_agent_and_the_localisation(run):
    out, text, records = run
    for agent in SQA_AGENTS:
        assert f"| {agent} | " in text
    assert "Localisation (glmap): within 1 m and 45 deg" in text
    assert (out / "summary.md").read_text().endswith(text.split("\n", 2)[2])
    assert {r["agent"] for r in records} == set(SQA_AGENTS)
    n = len(records) // len(SQA_AGENTS)
    assert n >= 3 and all(isinstance(r["em1"], bool) for r in records)
    # The room is read from what stands around the ground-truth pose (ROOM_CUES).
    rooms = [r for r in records if r["type"] == "room" and r["agent"] == "gt-pose"]
    assert rooms and all(r["supported"] for r in rooms), rooms
    assert sum(r["em1"] for r in rooms) >= len(rooms) / 2, rooms


def test_a_rerun_reuses_the_scene_results_and_other_settings_are_refused(run):
    out, _, records = run
    scene_file = next((out / "scenes").glob("*.json"))
    before = scene_file.stat().st_mtime_ns
    _, again = run_sqa_eval(SMALL, out, workers=1, progress=False)
    assert scene_file.stat().st_mtime_ns == before and again == records
    other = SqaSpec(**{**SMALL.__dict__, "situations": 4})
    with pytest.raises(InvalidInputError, match="other settings"):
        run_sqa_eval(other, out, workers=1, progress=False)
    assert json.loads(scene_file.read_text())["spec"] == SMALL.key()


def test_a_scene_file_cut_short_or_of_the_wrong_shape_is_answered_again(run, tmp_path):
    from glmap_tools.eval.sqa import _stored_scene

    out, _, records = run
    scene_file = next((out / "scenes").glob("*.json"))
    scene = scene_file.stem
    stored = json.loads(scene_file.read_text())
    assert _stored_scene(scene_file, scene) == stored
    first = stored["records"][0]
    bad_records = [
        {**first, "em1": "yes"},
        {**first, "scene": "elsewhere"},
        {k: v for k, v in first.items() if k != "agent"},
        {**first, "err_m": None},
        {**first, "situation_form": "plain"},  # forms in one record of the scene only
        7,
    ]
    path = tmp_path / f"{scene}.json"
    for record in bad_records:
        path.write_text(json.dumps({**stored, "records": [record, *stored["records"][1:]]}))
        assert _stored_scene(path, scene) is None, record
    for text in ("[]", "null", '{"scene": 3}', scene_file.read_text()[:-40], "\udcff"):
        path.write_text(text, errors="surrogateescape")
        assert _stored_scene(path, scene) is None
    # A run finds the cut file, answers the scene again and writes it whole.
    scene_file.write_text(scene_file.read_text()[:-40])
    _, again = run_sqa_eval(SMALL, out, workers=1, progress=False)
    assert len(again) == len(records) and _stored_scene(scene_file, scene) is not None


def test_an_unknown_sqa_agent_suggests_the_closest():
    with pytest.raises(InvalidInputError, match="Did you mean 'gt-pose'"):
        check_agents(["gt-pos"])


def test_two_stand_points_with_one_text_are_two_situations_in_the_localisation():
    from glmap_tools.eval.sqa_table import summarize

    def record(stand, err_m):
        return {
            "scene": "s00",
            "question_id": 0,
            "situation": "I am standing next to the bed, facing the desk.",
            "stand": stand,
            "type": "left",
            "agent": "glmap",
            "prediction": "",
            "answers": ["desk"],
            "em1": False,
            "em_r1": False,
            "supported": True,
            "seconds": 0.1,
            "err_m": err_m,
            "err_deg": 5.0,
        }

    text = summarize([record([1.0, 2.0, 0.5], 0.4), record([3.0, 2.0, 0.5], 2.0)], ["glmap"])
    assert "of 2 situations" in text and "0.50" in text  # one of the two located


def test_with_phrasings_the_report_has_reading_localisation_and_em_per_form(run):
    import dataclasses

    out, _, _ = run
    spec = dataclasses.replace(SMALL, phrasings=True, agents=("glmap", "text-only"))
    assert spec.key() != SMALL.key()
    phrased = out.parent / (out.name + "-phrased")
    phrased.mkdir()
    (phrased / "maps").symlink_to(out / "maps")  # the same tour map, built once
    text, records = run_sqa_eval(spec, phrased, workers=1, progress=False)
    assert "| situation form | held out | situations | reading | localised | EM-1 glmap |" in text
    assert "| question form | held out |" in text
    assert "held-out question forms:" in text and "tuned situation forms:" in text
    glmap = [r for r in records if r["agent"] == "glmap"]
    assert all("situation_form" in r and isinstance(r["reading_ok"], bool) for r in glmap)
    assert sum(r["read"] == r["type"] for r in glmap) >= 0.85 * len(glmap)
