"""The checks of the scripted episode catch a client that loses the server's state."""

from __future__ import annotations

from tests.frameworks import episode


def played(fresh_process_per_call: bool) -> list[episode.Reply]:
    """Replies of the scripted episode as a server that keeps (or loses) its state gives them."""
    replies: list[episode.Reply] = []
    steps, frames = 0, 0
    while (call := episode.next_call(replies)) is not None:
        tool, args = call
        if fresh_process_per_call and tool != "sim_reset":
            steps, frames = 0, 0  # a new server: no episode, an empty map
        taken = {"sim_reset": 0, "look_around": 12, "navigate_to": 5, "sim_step": 1}.get(tool, 0)
        taken = args.get("actions", taken)
        steps += taken
        frames += taken + (tool == "sim_reset")
        reply: dict = {"steps": steps, "episode": episode.EPISODE, "status": "running"}  # type: ignore[type-arg]
        if tool == "value_map":
            reply = {"waypoint": {"kind": "frontier", "xy": [1.0, 2.0]}}
        elif tool == "navigate_to":
            reply["walk_steps"] = 5
        elif tool == "sim_step":
            reply.update(status="stopped, not at the goal", spl=0.0)
        elif tool == "map_summary":
            reply = {"summary": {"frames": frames}}
        replies.append((tool, reply))
    return replies


def test_a_kept_episode_passes_and_a_lost_one_is_named():
    assert episode.problems(played(fresh_process_per_call=False)) == []
    lost = episode.problems(played(fresh_process_per_call=True))
    assert any(p.startswith("navigate_to reports step 5, expected 17") for p in lost), lost
    assert any("the map holds 0 frames" in p for p in lost), lost


def test_the_script_goes_to_a_goal_unit_when_the_value_map_found_one():
    reply = {"waypoint": {"kind": "goal", "unit_id": 7, "xy": [1.0, 2.0]}}
    assert episode.next_call([("value_map", reply)]) == (
        "navigate_to",
        {"unit_id": 7, "max_steps": episode.WALK},
    )
