"""The scripted ObjectNav episode every framework test plays through glmap-mcp.

Standard library only: the LangChain and smolagents tests import it from their own venvs.
A framework's test model asks `next_call` for its next tool call, given the replies so far
(tool name and the JSON of the reply's first text block); `problems` then checks that each
call continued the previous one: the step counter, the episode and the map are kept across
calls, so a client that loses the server's state between calls fails here.
"""

from __future__ import annotations

import json
from typing import Any

EPISODE = "tune/objectnav/s03-013"  # a bed around a corner, 2.8 m away
RESET = {"episode": EPISODE, "size": "160x120", "max_steps": 40}
WALK = 8  # navigate_to's action budget
NAV_ACTIONS = 2
LOOK_STEPS = 12  # look_around turns a full circle in 30 degree steps

Reply = tuple[str, dict[str, Any]]


def reply_json(text: str) -> dict[str, Any]:
    """A tool reply's first text block as JSON, with the text in the error when it is not."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise AssertionError(f"a tool reply is not JSON (a tool error?): {text[:500]!r}") from exc
    if not isinstance(data, dict):
        raise AssertionError(f"a tool reply is not a JSON object: {text[:500]!r}")
    return data


def next_call(replies: list[Reply]) -> tuple[str, dict[str, Any]] | None:
    """The next tool call after `replies`, or None when the episode is over."""
    if not replies:
        return "sim_reset", dict(RESET)
    tool, reply = replies[-1]
    if tool == "sim_reset":
        return "look_around", {}
    if tool == "look_around":
        return "value_map", {}
    if tool == "value_map":
        waypoint = reply["waypoint"]
        if waypoint["kind"] == "goal" and waypoint.get("unit_id") is not None:
            return "navigate_to", {"unit_id": waypoint["unit_id"], "max_steps": WALK}
        x, y = waypoint["xy"]
        return "navigate_to", {"x": x, "y": y, "max_steps": WALK}
    if tool == "navigate_to":
        return "nav_step", {"actions": NAV_ACTIONS}
    if tool == "nav_step":
        return "sim_step", {"action": "stop"}
    if tool == "sim_step":
        return "map_summary", {"include_image": False}
    return None


TOOLS = ["sim_reset", "look_around", "value_map", "navigate_to", "nav_step", "sim_step"]


def problems(replies: list[Reply]) -> list[str]:
    """What is wrong with a played episode (empty when the state was kept from call to call)."""
    tools = [tool for tool, _ in replies]
    if tools != [*TOOLS, "map_summary"]:
        return [f"calls {tools}, expected {[*TOOLS, 'map_summary']}"]
    got = dict(replies)
    out = []
    walked = got["navigate_to"].get("walk_steps", -1)
    expected = {
        "sim_reset": 0,
        "look_around": LOOK_STEPS,
        "navigate_to": LOOK_STEPS + walked,
        "nav_step": LOOK_STEPS + walked + NAV_ACTIONS,
        "sim_step": LOOK_STEPS + walked + NAV_ACTIONS + 1,
    }
    for tool, steps in expected.items():
        if got[tool].get("steps") != steps:
            out.append(f"{tool} reports step {got[tool].get('steps')}, expected {steps}")
        if got[tool].get("episode") != EPISODE:
            out.append(f"{tool} plays {got[tool].get('episode')!r}, expected {EPISODE!r}")
    if not 1 <= walked <= WALK:
        out.append(f"navigate_to walked {walked} steps, expected 1..{WALK}")
    final = got["sim_step"]
    if final.get("status") == "running" or "spl" not in final:
        out.append(f"the episode did not end on stop: {final}")
    frames = got["map_summary"].get("summary", {}).get("frames")
    if frames != expected["sim_step"] + 1:
        out.append(f"the map holds {frames} frames, expected {expected['sim_step'] + 1}")
    return out
