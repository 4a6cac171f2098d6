"""sim_reset and sim_step through an in-memory client: frames flow into the session's map."""

from __future__ import annotations

import json
import os

import pytest
from mcp import Client

from glmap_tools.server import build_server
from tests.test_server_fixtures import config

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def status(result) -> dict:  # type: ignore[no-untyped-def, type-arg]
    assert not result.is_error, result.content[0].text
    assert [b.type for b in result.content] == ["text", "image"]
    assert result.content[1].mime_type == "image/jpeg"
    return json.loads(result.content[0].text)


async def test_a_chat_user_can_play_an_episode_that_builds_the_map(tmp_path):
    server = build_server(config(tmp_path, sim_size=(168, 126), sim_max_steps=6))
    async with Client(server) as client:
        start = status(await client.call_tool("sim_reset", {"scene": 0, "seed": 3}))
        assert start["status"] == "running" and start["steps"] == 0 and start["goal"]
        assert "distance_to_goal" not in start  # no ground truth while playing
        turned = status(await client.call_tool("sim_step", {"action": "turn_left", "repeat": 3}))
        assert turned["steps"] == 3 and len(turned["map_updates"]) == 3
        assert turned["heading_deg"] != start["heading_deg"]
        summary = json.loads(
            (await client.call_tool("map_summary", {"include_image": False})).content[0].text
        )["summary"]
        assert summary["frames"] == 4 and summary["instances"] >= 1
        unknown = await client.call_tool("sim_step", {"action": "jump"})
        assert unknown.is_error and "'move_forward'" in unknown.content[0].text
        ended = status(await client.call_tool("sim_step", {"action": "stop"}))
        assert ended["status"] in ("success", "stopped, not at the goal")
        assert "spl" in ended and "distance_to_goal" in ended
        after = await client.call_tool("sim_step", {"action": "move_forward"})
        assert after.is_error and "call sim_reset" in after.content[0].text
        again = json.loads(
            (await client.call_tool("map_summary", {"include_image": False})).content[0].text
        )["summary"]
        assert again["frames"] == 5  # the refused steps added nothing


async def test_a_goal_can_be_chosen_and_a_wrong_one_gets_the_closest_suggestion(tmp_path):
    server = build_server(config(tmp_path, sim_size=(96, 72)))
    async with Client(server) as client:
        chosen = status(await client.call_tool("sim_reset", {"scene": 0, "goal": "Sofa"}))
        wrong = await client.call_tool("sim_reset", {"scene": 0, "goal": "sofaa"})
        never = await client.call_tool("sim_step", {"action": "stop", "session": "nope"})
    assert chosen["goal"] == "sofa"
    assert wrong.is_error and "Did you mean 'sofa'?" in wrong.content[0].text
    assert never.is_error and "session 'nope' does not exist" in never.content[0].text


async def test_stepping_before_any_reset_says_to_reset_first(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("sim_step", {"action": "move_forward"})
    assert result.is_error and "call sim_reset first" in result.content[0].text


async def test_the_image_size_and_step_limit_can_be_chosen_at_reset(tmp_path):
    import base64

    import cv2
    import numpy as np

    async with Client(build_server(config(tmp_path))) as client:
        start = await client.call_tool("sim_reset", {"size": "160x120", "max_steps": 2})
        first = status(start)
        status(await client.call_tool("sim_step", {"action": "turn_left"}))
        last = status(await client.call_tool("sim_step", {"action": "turn_left"}))
        bad = await client.call_tool("sim_reset", {"size": "100x100"})
    jpeg = np.frombuffer(base64.b64decode(start.content[1].data), np.uint8)
    assert cv2.imdecode(jpeg, cv2.IMREAD_COLOR).shape == (120, 160, 3)
    assert first["max_steps"] == 2 and last["status"] == "out of steps"
    assert bad.is_error and "320x240" in bad.content[0].text


def test_an_action_on_an_episode_a_reset_replaced_is_refused_saying_so():
    # Issue 27 item 4: sim_step racing sim_reset answered "this SceneRenderer was closed".
    from glmap_tools.app import simulator
    from glmap_tools.errors import InvalidInputError

    sim = simulator.open_episode("objectnav", 0, (96, 72), 20)
    simulator.reset(sim, 0, None)
    seen = sim.resets
    simulator.step(sim, "turn_left", seen)
    simulator.reset(sim, 1, None)  # same env, a new episode
    with pytest.raises(InvalidInputError, match="was reset by another call"):
        simulator.step(sim, "turn_left", seen)
    assert len(sim.actions) == 0  # nothing was played in the new episode
    sim.close()  # another scene's sim_reset closes the env
    with pytest.raises(InvalidInputError, match="was reset by another call"):
        simulator.step(sim, "turn_left")


async def test_sim_step_racing_sim_reset_on_one_session_finishes_or_says_it_was_reset(tmp_path):
    import anyio

    server = build_server(config(tmp_path, sim_size=(96, 72), sim_max_steps=50))
    async with Client(server) as client:
        status(await client.call_tool("sim_reset", {"scene": 0, "seed": 3}))
        stepping = anyio.Event()
        out: dict[str, object] = {}

        async def progress(done: float, total: float | None, message: str | None) -> None:
            if done >= 1:
                stepping.set()

        async def step() -> None:
            out["step"] = await client.call_tool(
                "sim_step", {"action": "turn_left", "repeat": 20}, progress_callback=progress
            )

        async def reset() -> None:
            await stepping.wait()
            out["reset"] = await client.call_tool("sim_reset", {"scene": 1, "seed": 0})

        async with anyio.create_task_group() as tg:
            tg.start_soon(step)
            tg.start_soon(reset)
        status(out["reset"])
        stepped = out["step"]
        if stepped.is_error:  # type: ignore[attr-defined]
            text = stepped.content[0].text  # type: ignore[attr-defined]
            assert "was reset by another call" in text and "SceneRenderer" not in text, text
        after = status(await client.call_tool("sim_step", {"action": "turn_right"}))
        assert after["steps"] == 1, after
