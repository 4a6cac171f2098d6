"""Seeded episodes replay as recorded: actions, poses, goal matches and the map's instances.

The golden file comes from `python -m glmap_tools.regression.replay --golden`; rewrite it
only for a change meant to change how the agent moves or what the map holds, and say so.
"""

import json

import pytest

from glmap_tools.regression.replay import GOLDEN, GOLDEN_EPISODES, golden_record

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def replayed():
    return golden_record()


@pytest.mark.parametrize("k", range(len(GOLDEN_EPISODES)))
def test_a_seeded_episode_takes_the_recorded_actions_through_the_recorded_poses(replayed, k):
    want = json.loads(GOLDEN.read_text())[k]
    got = replayed[k]
    assert got["episode"] == want["episode"]
    assert got["actions"] == want["actions"]
    assert got["poses"] == want["poses"]
    assert got["matched"] == want["matched"]


@pytest.mark.parametrize("k", range(len(GOLDEN_EPISODES)))
def test_a_seeded_episode_builds_the_recorded_instances(replayed, k):
    want = json.loads(GOLDEN.read_text())[k]
    assert [list(i) for i in replayed[k]["instances"]] == want["instances"]
