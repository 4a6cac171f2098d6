"""The client's f_S agents (agents/fs.py): the oracle room prior from a scene's ground truth,
recorded scores, and an episode that sends its region scores through value_map."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from agents.fs import OracleRoom, Recorded, RegionView, region_scorer, region_views, split_agent
from agents.runner import open_session, run_episode
from glmap_tools.errors import InvalidInputError
from glmap_tools.worlds.splits import bench_episode, bench_layout, load_split
from tests.test_server_fixtures import config

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
HOUSE = load_split("house-tune", "objectnav")[0]


def test_an_agent_name_splits_into_policy_and_f_s_source():
    assert split_agent("glmap+oracle-room") == ("glmap", "oracle-room")
    assert split_agent("frontier") == ("frontier", None)
    with pytest.raises(InvalidInputError, match="not one of"):
        region_scorer("psychic", HOUSE.episode_id)


def test_the_oracle_scores_regions_in_the_goal_s_kind_of_room_1_and_the_rest_0():
    oracle = OracleRoom.for_episode(HOUSE.episode_id)
    layout = bench_layout(HOUSE.layout_path)
    rooms = {r.id: r for r in layout.rooms}
    goal = [o for o in layout.objects if o.id in HOUSE.episode.goal_object_ids]
    assert oracle.goal_kinds == {rooms[o.room].type for o in goal}
    other = next(r for r in layout.rooms if r.type not in oracle.goal_kinds)
    inside_other = tuple(float(v) for v in np.mean(other.polygon, axis=0))
    views = [
        RegionView(1, "seating area", (float(goal[0].position[0]), float(goal[0].position[1]))),
        RegionView(2, "somewhere else", inside_other),  # type: ignore[arg-type]
        RegionView(3, "no members", None),
    ]
    assert oracle.score(HOUSE.episode.goal_text, views) == {1: 1.0, 2: 0.0, 3: 0.0}
    wrong = region_scorer("wrong-room", HOUSE.episode_id)
    assert wrong.score(HOUSE.episode.goal_text, views) == {1: 0.0, 2: 1.0, 3: 0.0}


def test_a_region_s_place_is_the_mean_of_its_members_centroids():
    regions = [{"id": 9, "description": "a", "instance_ids": [1, 2]}, {"id": 8, "description": "b"}]
    instances = [{"id": 1, "centroid": [0, 0, 1]}, {"id": 2, "centroid": [2, 4, 0]}]
    views = region_views(regions, instances)
    assert views[0] == RegionView(9, "a", (1.0, 2.0)) and views[1].xy is None


def test_recorded_scores_are_read_by_goal_and_text_and_bad_lines_are_named(tmp_path):
    good = tmp_path / "scores.jsonl"
    good.write_text(
        json.dumps({"goal": "Sofa", "text": "seating  area: a sofa", "score": 0.9}) + "\n\n"
    )
    rec = Recorded.from_file(good)
    views = [RegionView(4, "Seating area: a sofa", None), RegionView(5, "laundry", None)]
    assert rec.score("sofa", views) == {4: 0.9} and rec.missing == {"laundry"}
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"goal": "sofa", "text": "x", "score": 1.5}\n')
    with pytest.raises(InvalidInputError, match=r"bad.jsonl:1.*\[0, 1\]"):
        Recorded.from_file(bad)
    bad.write_text('{"goal": "sofa"}\n')
    with pytest.raises(InvalidInputError, match="bad.jsonl:1 is not"):
        Recorded.from_file(bad)
    with pytest.raises(InvalidInputError, match="does not exist"):
        Recorded.from_file(tmp_path / "none.jsonl")


@pytest.mark.anyio
async def test_an_oracle_episode_sends_region_scores_through_value_map(tmp_path):
    out = tmp_path / "ep"
    async with open_session(config(tmp_path, sim_size=(160, 120))) as session:
        result = await run_episode(
            session, HOUSE.episode_id, "glmap+oracle-room", seed=3, out_dir=out, max_steps=40
        )
    calls = [json.loads(line) for line in (out / "trace.jsonl").read_text().splitlines()]
    given = [c for c in calls if c["tool"] == "value_map"]
    assert given, "no region scores were sent"
    assert result.agent == "glmap+oracle-room" and result.tool_calls == len(calls)
    for c in given:
        assert set(c["arguments"]) == {"scores"}
        assert set(c["arguments"]["scores"].values()) <= {0.0, 1.0}
        held = json.loads(c["texts"][0])["client"]["scores"]
        assert all(kind == "region" for _, kind, _ in held)
    # nav_step reads them: its calls after the first scores say so
    after = [c for c in calls[calls.index(given[0]) :] if c["tool"] == "nav_step"]
    assert after and json.loads(after[0]["texts"][0])["client_scores"]["units"] >= 1


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def test_the_oracle_needs_a_benchmark_episode():
    with pytest.raises(Exception, match="episode id"):
        OracleRoom.for_episode("")
    assert bench_episode(HOUSE.episode_id).split == "house-tune"
