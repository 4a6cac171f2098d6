"""The failure taxonomy: how an episode ended, counted per agent in the eval summary."""

from __future__ import annotations

import pytest

from glmap_tools.eval.table import markdown, summarize
from glmap_tools.sim.outcome import OUTCOMES, episode_outcome


@pytest.mark.parametrize(
    ("args", "kind"),
    [
        ((True, False, 0.0, True, True), "success"),
        ((False, False, 0.6, True, True), "stopped short"),
        ((False, False, 4.0, True, True), "stopped at a false positive"),
        ((False, False, 4.0, True, True, True), "stopped at another instance"),
        ((False, False, 0.6, True, True, True), "stopped short"),
        ((False, False, 4.0, False, False), "stopped at a false positive"),
        ((False, True, 4.0, False, False), "goal never seen"),
        ((False, True, 4.0, True, False), "goal seen, not recognised"),
        ((False, True, 0.5, True, True), "timeout"),
    ],
)
def test_an_ended_episode_falls_in_the_first_kind_that_applies(args, kind) -> None:
    assert episode_outcome(*args) == kind


def test_the_summary_counts_each_agents_outcomes_in_the_taxonomys_order() -> None:
    def rec(ok: bool, kind: str) -> dict:
        return {"success": ok, "spl": 0.5 * ok, "distance_to_goal": 0.0, "steps": 9,
                "tool_calls": 10, "outcome": kind}  # fmt: skip

    records = {
        "glmap": {"a": rec(True, "success"), "b": rec(False, "goal never seen")},
        "frontier": {"a": rec(False, "stopped at a false positive"), "b": rec(False, "timeout")},
    }
    summary = summarize(records, ["glmap", "frontier"], resamples=50)
    assert list(summary.outcomes["glmap"]) == list(OUTCOMES)
    assert summary.outcomes["glmap"]["goal never seen"] == 1
    assert summary.outcomes["frontier"]["stopped at a false positive"] == 1
    table = markdown(summary)
    assert "| How episodes ended | success | stopped short |" in table
    assert "| frontier | 0 | 0 | 0 | 1 | 0 | 0 | 1 |" in table
    assert summary.to_json()["outcomes"]["glmap"]["success"] == 1


def test_the_env_reports_whether_the_goal_was_seen_and_recognised() -> None:
    import os

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from glmap_tools.sim.env import ObjectNavEnv
    from glmap_tools.sim.render import CameraSpec

    env = ObjectNavEnv(scene_seed=3, camera=CameraSpec(96, 72), max_steps=40)
    _, info = env.reset(seed=1)
    seen = [info["goal_seen"]]
    for _ in range(12):  # a full turn on the spot
        info = env.step(2)[4]
        seen.append(info["goal_seen"])
        assert info["goal_recognised"] == info["goal_seen"]  # gt perception names what it sees
    assert seen == sorted(seen)  # once seen, seen for the rest of the episode
    env.reset(seed=1)
    assert env.step(0)[4]["goal_seen"] == seen[0]  # a new episode starts unseen
    env.close()


def test_an_instnav_stop_beside_another_instance_of_the_category_is_told_apart() -> None:
    """InstNav: a stop within reach of an object of the goal's category that is not the
    described one is 'stopped at another instance', not a false positive."""
    import os

    import numpy as np

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from glmap_tools.sim.env import InstNavEnv
    from glmap_tools.sim.motion import AgentState
    from glmap_tools.sim.reach import reaches
    from glmap_tools.sim.render import CameraSpec

    env = InstNavEnv(scene_seed=3, camera=CameraSpec(32, 24), max_steps=40)
    for seed in range(40):
        env.reset(seed=seed)
        goal = env.layout.object(env.episode.goal_object_ids[0])
        others = [o for o in env.layout.objects if o.category == goal.category and o.id != goal.id]
        if others:
            break
    assert others, "no InstNav episode with two instances of the goal's category"
    rows, cols = np.nonzero(env.grid.navigable)
    cells = env.grid.to_world(np.stack([rows, cols], axis=1))
    beside = reaches(env.grid, others[0], cells, env.success_distance)
    beside &= ~reaches(env.grid, goal, cells, env.success_distance + 1.0)
    beside &= np.array([env.distance_to_goal(AgentState(x, y, 0.0)) > 1.0 for x, y in cells])
    assert beside.any()
    x, y = cells[np.nonzero(beside)[0][0]]
    env.state = AgentState(float(x), float(y), 0.0)
    info = env.step(0)[4]
    assert not info["success"] and info["stopped_at_goal_category"]
    kind = episode_outcome(False, False, info["distance_to_goal"], True, True, True)
    assert kind == "stopped at another instance"
    env.reset(seed=seed)
    assert not env.step(0)[4]["stopped_at_goal_category"]  # this start reaches no other instance
    env.close()
