"""Text search ranks by label and description over phrasings, and flags calibrated matches.

The full quality figures (top-1, MRR, match precision/recall on both halves of the labelled
query set) come from `python -m glmap_tools.bench search`; these tests hold the mechanisms
and the examples the figures are about.
"""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from mcp import Client

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.minilm import default_embedder
from glmap_tools.map import queries
from glmap_tools.server import build_server
from glmap_tools.worlds import search_eval as se
from glmap_tools.worlds.generator import generate_apartment
from glmap_tools.worlds.search_queries import build, default_queries_path
from tests.test_server_fixtures import config, frame_args


@functools.lru_cache(maxsize=4)
def minilm_scene(seed: int) -> se.SceneMap:
    return se.scene_map(generate_apartment(seed), default_embedder())


def labels(hits) -> list[str]:  # type: ignore[no-untyped-def]
    return [h.label for h in hits]


def test_somewhere_to_sleep_ranks_the_beds_above_the_nightstands():
    glmap = minilm_scene(1).glmap  # two beds, three nightstands
    hits = glmap.find_instances("somewhere to sleep", k=3)
    assert labels(hits)[:2] == ["bed", "bed"]


def test_something_to_sit_on_puts_seats_first_and_no_toaster_near_the_top():
    glmap = minilm_scene(0).glmap  # a sofa and a toaster, no chair
    hits = glmap.find_instances("something to sit on", k=3)
    assert hits[0].label == "sofa"
    assert "toaster" not in labels(hits)


def test_a_thing_the_scene_does_not_have_is_not_a_match():
    glmap = minilm_scene(0).glmap
    for query in ("a grand piano", "a bicycle", "an aquarium with fish"):
        hits = glmap.find_instances(query, k=5)
        assert hits and not any(h.match for h in hits), query


def test_a_region_asked_for_by_its_use_is_found_and_matches():
    sm = minilm_scene(1)
    hits = sm.glmap.find_regions("where to prepare food", k=2)
    assert hits[0].description.startswith("cooking area")
    assert hits[0].match is True


@pytest.mark.parametrize(
    ("query", "expected"),
    [
        ("somewhere to sleep", ["somewhere to sleep", "sleep"]),
        ("Where can I wash my hands?", ["Where can I wash my hands?", "wash my hands"]),
        ("something to sit on", ["something to sit on", "sit on"]),
        ("a device for making toast", ["a device for making toast", "making toast"]),
        ("a place to lie down at night", ["a place to lie down at night", "lie down at night"]),
        ("the red chair", ["the red chair"]),
        ("where", ["where"]),
    ],
)
def test_a_query_asking_for_a_use_adds_the_bare_activity_as_a_phrasing(query, expected):
    assert queries.phrasings(query) == expected


def test_the_fast_scores_equal_the_reference_per_phrasing_and_per_field():
    sm = se.scene_map(generate_apartment(2), HashingEmbedder())
    for kind in ("instance", "region"):
        for text in ("somewhere to sleep", "the grey sofa", "where to cook"):
            ids, fast = queries.text_scores(sm.glmap, kind, text)
            ref_ids, ref = queries.reference_text_scores(sm.glmap, kind, text)
            assert np.array_equal(ids, ref_ids)
            np.testing.assert_allclose(fast, ref, atol=1e-5)


def test_an_instance_without_a_label_is_scored_by_its_description_alone():
    sm = se.scene_map(generate_apartment(2), HashingEmbedder())
    glmap = sm.glmap
    uid = min(glmap.instances)
    unit = glmap.instances[uid]
    glmap.instances[uid] = type(unit)(
        uid, "", unit.text, unit.embedding, unit.gaussians, 1, 0, 0
    )  # a unit observed without a category
    glmap._matrix_cache.clear()
    ids, scores = queries.text_scores(glmap, "instance", unit.text)
    row = int(np.flatnonzero(ids == uid)[0])
    assert scores[row] == pytest.approx(1.0, abs=1e-5)  # its own description, unmixed


def test_hits_carry_no_match_flag_when_the_embedder_declares_no_threshold():
    class Bare:  # an embedder with only the protocol's fields
        name, dim, default_tau_s = "bare", 512, 0.5
        inner = HashingEmbedder()

        def embed(self, texts):  # type: ignore[no-untyped-def]
            return self.inner.embed(texts)

    glmap = se.scene_map(generate_apartment(2), Bare()).glmap  # type: ignore[arg-type]
    hits = glmap.find_instances("a sofa", k=2)
    assert [h.match for h in hits] == [None, None]
    assert hits[0].score is not None


def test_the_match_flag_is_the_score_against_the_embedders_threshold():
    glmap = se.scene_map(generate_apartment(2), HashingEmbedder()).glmap
    tau = HashingEmbedder.default_tau_match
    sofa = next(u for u in glmap.instances.values() if u.label == "sofa")
    hits = glmap.find_instances(sofa.text, k=len(glmap.instances))
    assert any(h.match for h in hits) and not all(h.match for h in hits)
    assert all(h.match == (h.score >= tau - 5e-5) for h in hits if abs(h.score - tau) > 1e-4)


@pytest.mark.anyio
@pytest.mark.parametrize("anyio_backend", ["asyncio"])
async def test_find_instance_over_mcp_says_whether_each_hit_matches(tmp_path, anyio_backend):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        found = await client.call_tool("find_instance", {"query": "blue office chair"})
        missing = await client.call_tool("find_instance", {"query": "a grand piano"})
        region = await client.call_tool("find_region", {"query": "dining corner"})
    assert found.structured_content["hits"][0]["match"] is True
    assert not any(h["match"] for h in missing.structured_content["hits"])
    assert region.structured_content["hits"][0]["match"] is True


def test_the_query_set_file_is_what_its_builder_writes_for_the_first_scene():
    rows = [json.loads(line) for line in default_queries_path().read_text().splitlines()]
    first = build({"tune": (0,)})
    assert rows[: len(first)] == first


def test_the_query_set_has_100_queries_and_halves_sharing_no_scene_or_wording():
    qs = se.load_queries()
    tune = [q for q in qs if q.split == "tune"]
    held = [q for q in qs if q.split == "held_out"]
    assert len(qs) >= 100 and len(tune) >= 50 and len(held) >= 50
    assert not {q.scene for q in tune} & {q.scene for q in held}
    shared = {q.query for q in tune} & {q.query for q in held}
    assert not shared - {q.query for q in qs if q.phrasing == "colour"}
    assert any(not q.answers for q in tune) and any(not q.answers for q in held)


def test_a_bad_query_line_names_the_line_and_the_fields(tmp_path):
    path = tmp_path / "q.jsonl"
    path.write_text('{"id": "q1", "split": "tune"}\n')
    with pytest.raises(InvalidInputError, match=r"q.jsonl:1: expected a JSON query with id"):
        se.load_queries(path)
    path.write_text(
        '{"id": "q1", "split": "train", "scene": 0, "kind": "instance", "query": "x", '
        '"phrasing": "name", "answers": []}\n'
    )
    with pytest.raises(InvalidInputError, match=r"split 'train'"):
        se.load_queries(path)


def test_metrics_count_top1_mrr_and_top_hit_matches():
    def q(answers):  # type: ignore[no-untyped-def]
        return se.Query("q", "tune", 0, "instance", "x", "name", tuple(answers))

    outcomes = [
        se.Outcome(q([1]), [1, 2], [0.9, 0.1], [True, False]),  # right, matched
        se.Outcome(q([2]), [1, 2], [0.6, 0.5], [True, True]),  # wrong top, matched: false match
        se.Outcome(q([]), [3, 1], [0.2, 0.1], [False, False]),  # nothing to find, no match
    ]
    m = se.metrics(outcomes)
    assert m.top1 == 0.5 and m.mrr == pytest.approx(0.75)
    assert m.match_precision == 0.5 and m.match_recall == 1.0
    assert m.hit_precision == pytest.approx(2 / 3) and m.hit_recall == 1.0


@pytest.mark.slow  # embeds the tuning half of the query set with MiniLM (about 10 s)
@pytest.mark.parametrize("make", [HashingEmbedder, default_embedder], ids=["hashing", "minilm"])
def test_each_embedders_match_threshold_is_what_calibration_finds(make):
    """The declared `default_tau_match` is `calibrate()` on the tuning half, to 2 decimals."""
    embedder = make()
    tune = [q for q in se.load_queries() if q.split == "tune"]
    found, _ = se.calibrate(se.run_queries(tune, embedder))
    assert round(found, 2) == embedder.default_tau_match
