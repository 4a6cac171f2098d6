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
    assert "| frontier | 0 | 0 | 1 | 0 | 0 | 1 |" in table
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
