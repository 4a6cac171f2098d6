"""Navigation tools through an in-memory client: look_around, value_map, frontiers,
navigate_to, nav_step, and the agent's distance and bearing on map hits."""

from __future__ import annotations

import dataclasses
import json
import os

import cv2
import numpy as np
import pytest
from mcp import Client

from glmap_tools.bench.calls import play
from glmap_tools.server import ServerConfig, build_server
from glmap_tools.worlds.splits import load_split
from tests.test_server_fixtures import config, counts, frame_args

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio
BENCH = load_split("tune", "objectnav")[0]
EPISODE = BENCH.episode_id


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def ok(result) -> dict:  # type: ignore[no-untyped-def, type-arg]
    assert not result.is_error, result.content[0].text
    return json.loads(result.content[0].text)


def image(block) -> np.ndarray:  # type: ignore[no-untyped-def]
    import base64

    data = np.frombuffer(base64.b64decode(block.data), np.uint8)
    return cv2.imdecode(data, cv2.IMREAD_COLOR)


async def chat_episode(client: Client, reset: dict, budget: int = 10) -> tuple[dict, list[str]]:  # type: ignore[type-arg]
    """What a chat client does: look around, ask the value map, walk, repeat; stop at the goal."""
    calls: list[str] = []

    async def call(tool: str, args: dict) -> dict:  # type: ignore[type-arg]
        calls.append(tool)
        return ok(await client.call_tool(tool, args))

    await call("sim_reset", reset)
    await call("look_around", {})
    while len(calls) <= budget - 4:
        waypoint = (await call("value_map", {}))["waypoint"]
        if waypoint["kind"] == "goal":
            await call("navigate_to", {"unit_id": waypoint["unit_id"]})
            break
        await call("navigate_to", {"x": waypoint["xy"][0], "y": waypoint["xy"][1]})
        await call("look_around", {})
    return await call("sim_step", {"action": "stop"}), calls


# InstNav s00-000 takes 99 steps; the 310 of s01-000 (27 s of CI) are the 150-action call of
# tests/tool_texts.py, which plays that episode.
CHAT_EPISODES = [f"bench/objectnav/s{k:02d}-000" for k in (0, 1, 4, 5, 7)] + [
    "bench/instnav/s00-000"
]


@pytest.mark.slow  # loads MiniLM; plays a bench episode (one test each, to spread over workers)
@pytest.mark.parametrize("episode", CHAT_EPISODES)
async def test_a_chat_client_finishes_a_bench_episode_in_at_most_ten_calls(tmp_path, episode):
    defaults = ServerConfig(maps_dir=tmp_path / "maps", warm_up=False)  # MiniLM, 320x240
    async with Client(build_server(defaults)) as client:
        final, calls = await play(client, episode)  # as docs/mcp.md tells a client
    assert final["status"] == "success", (episode, final, calls)
    assert len(calls) <= 10 and calls[0] == "sim_reset" and calls[-1] == "sim_step"


@pytest.mark.slow  # loads MiniLM (the hashing embedder does not match goals well)
async def test_a_chat_client_steering_with_value_map_and_navigate_to_needs_ten_calls(tmp_path):
    minilm = dataclasses.replace(config(tmp_path), embedder="minilm")  # scores goals well
    server = build_server(dataclasses.replace(minilm, sim_size=(160, 120)))
    async with Client(server) as client:
        # A bed 2.8 m away around a corner: look, walk to a frontier, look, walk to the bed.
        final, calls = await chat_episode(client, {"episode": "tune/objectnav/s03-013"})
    assert final["status"] == "success", (final, calls)
    assert len(calls) <= 10 and calls[0] == "sim_reset" and calls[-1] == "sim_step"


async def test_look_around_turns_a_full_circle_and_returns_one_labelled_contact_sheet(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        start = ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        result = await client.call_tool("look_around", {})
        turned = ok(result)
        frames, _, _ = await counts(client)
    assert start["episode"] == EPISODE and start["goal"] == BENCH.episode.goal_text
    assert turned["steps"] == 12 and turned["heading_deg"] == pytest.approx(start["heading_deg"])
    assert [b.type for b in result.content] == ["text", "image"]
    sheet = image(result.content[1])
    assert sheet.shape[1] == 4 * 213 and sheet.shape[0] == 3 * 160  # 4 x 3 frames, labelled
    assert frames == 13


async def test_value_map_and_frontiers_describe_where_to_go_from_the_agent(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        empty = await client.call_tool("value_map", {})
        ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        ok(await client.call_tool("look_around", {}))
        result = await client.call_tool("value_map", {"units": "instances"})
        value = ok(result)
        fronts = ok(await client.call_tool("frontiers", {"top_k": 3}))
    assert empty.is_error and "no goal" in empty.content[0].text
    assert value["goal"] == BENCH.episode.goal_text and value["units"] == "instances"
    assert value["waypoint"]["kind"] in ("goal", "frontier", "explore")
    assert {"distance_m", "bearing_deg", "reason"} <= set(value["waypoint"])
    assert all(0.0 <= v <= 1.0 for _, _, v in value["top_cells"])
    assert result.content[1].mime_type == "image/png" and image(result.content[1]).shape[0] > 64
    assert 1 <= len(fronts["frontiers"]) <= 3 and fronts["total"] >= len(fronts["frontiers"])
    paths = [f["path_m"] for f in fronts["frontiers"]]
    assert paths == sorted(paths)
    for f in fronts["frontiers"]:
        assert f["cells"] >= 1 and -180 <= f["bearing_deg"] <= 180


async def test_navigate_to_walks_next_to_a_unit_and_every_frame_goes_into_the_map(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        ok(await client.call_tool("sim_reset", {"scene": 0, "goal": "sofa", "seed": 1}))
        ok(await client.call_tool("look_around", {}))
        hits = await client.call_tool("find_instance", {"query": "sofa", "top_k": 1})
        sofa = hits.structured_content["hits"][0]
        walk = ok(await client.call_tool("navigate_to", {"unit_id": sofa["id"], "max_steps": 60}))
        frames, _, _ = await counts(client)
        stop = ok(await client.call_tool("sim_step", {"action": "stop"}))
    assert walk["outcome"] == "reached" and walk["walk_steps"] > 0 and walk["walked_m"] > 0
    assert walk["unit_id"] == sofa["id"] and walk["would_succeed"] and walk["in_sight"]
    assert walk["unit_distance_m"] <= 0.75 and walk["remaining_m"] == 0.0
    assert "blocked_by" not in walk
    assert walk["steps"] == 12 + walk["walk_steps"]
    assert frames == 13 + walk["walk_steps"]
    assert stop["status"] == "success"


async def test_navigate_to_refuses_bad_targets_and_changes_nothing(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        before_reset = await client.call_tool("navigate_to", {"x": 1.0, "y": 1.0})
        ok(await client.call_tool("sim_reset", {"scene": 0, "goal": "sofa", "seed": 1}))
        ok(await client.call_tool("look_around", {}))
        hits = await client.call_tool("find_instance", {"query": "sofa", "top_k": 1})
        sofa = hits.structured_content["hits"][0]
        outside = await client.call_tool("navigate_to", {"x": 80.0, "y": 1.0})
        inside = await client.call_tool(
            "navigate_to", {"x": sofa["centroid"][0], "y": sofa["centroid"][1]}
        )
        both = await client.call_tool("navigate_to", {"x": 1.0, "y": 1.0, "unit_id": 1})
        unknown = await client.call_tool("navigate_to", {"unit_id": 999})
        after = ok(await client.call_tool("sim_step", {"action": "turn_left"}))
    assert before_reset.is_error and "call sim_reset first" in before_reset.content[0].text
    assert outside.is_error and "outside the map" in outside.content[0].text
    assert "spans x" in outside.content[0].text
    assert inside.is_error and "Nearest reachable point: (" in inside.content[0].text
    assert both.is_error and "not both" in both.content[0].text
    assert unknown.is_error and "999" in unknown.content[0].text
    assert after["steps"] == 13  # the refused calls took no step
    assert len(after["map_updates"]) == 1


async def test_map_hits_carry_distance_and_bearing_from_the_agent_during_an_episode(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        assert not (await client.call_tool("observe_frame", frame_args())).is_error
        plain = await client.call_tool("find_instance", {"query": "chair"})
        start = ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        ok(await client.call_tool("look_around", {}))
        hits = (await client.call_tool("find_instance", {"query": "a bed"})).structured_content
        near = await client.call_tool("what_is_at", {"x": 3.0, "y": 3.0, "radius": 5.0})
    assert plain.structured_content["from_agent"] == []
    assert [h["id"] for h in hits["hits"]] == [r["id"] for r in hits["from_agent"]]
    x, y = start["position"]
    for hit, rel in zip(hits["hits"], hits["from_agent"], strict=True):
        cx, cy = hit["centroid"][:2]
        assert rel["distance_m"] == pytest.approx(np.hypot(cx - x, cy - y), abs=0.01)
        bearing = np.degrees(np.arctan2(cy - y, cx - x)) - start["heading_deg"]
        assert (rel["bearing_deg"] - bearing + 180) % 360 - 180 == pytest.approx(0, abs=0.2)
    assert len(near.structured_content["from_agent"]) == len(near.structured_content["units"])


async def test_nav_step_acts_with_a_policy_and_attaches_images_on_request(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        quiet = await client.call_tool("nav_step", {"policy": "frontier", "actions": 3})
        detailed = await client.call_tool("nav_step", {"policy": "frontier", "details": True})
        shown = await client.call_tool("nav_step", {"policy": "glmap", "images": True})
        wrong = await client.call_tool("nav_step", {"policy": "glmapp"})
    summary = ok(quiet)
    assert summary["outcome"] == "actions done" and sum(summary["actions"].values()) == 3
    assert [d["step"] for d in summary["last"]] == [1, 2, 3] and "decisions" not in summary
    assert len(quiet.content) == 1 and len(quiet.content[0].text) < 1500
    assert summary["waypoint"]["kind"] and summary["waypoint"]["reason"]
    (d,) = ok(detailed)["decisions"]
    assert d["step"] == 4 and d["action"] in ("move_forward", "turn_left", "turn_right")
    assert d["waypoint"]["kind"] and d["waypoint"]["reason"]
    assert ok(shown)["steps"] == 5
    assert [b.mime_type for b in shown.content[1:]] == ["image/jpeg", "image/png"]
    assert wrong.is_error and "glmap" in wrong.content[0].text


async def test_a_benchmark_episode_id_with_a_typo_gets_the_closest_suggestion(tmp_path):
    async with Client(build_server(config(tmp_path, sim_size=(96, 72)))) as client:
        wrong = await client.call_tool("sim_reset", {"episode": "tune/objectnav/s00-09"})
        both = await client.call_tool("sim_reset", {"episode": EPISODE, "goal": "sofa"})
        unstarted = await client.call_tool("look_around", {})
    assert wrong.is_error and "Did you mean" in wrong.content[0].text
    assert both.is_error and "not both" in both.content[0].text
    assert unstarted.is_error and "call sim_reset first" in unstarted.content[0].text


@pytest.mark.parametrize("new_env", [False, True])
async def test_a_refused_sim_reset_keeps_the_running_episode(tmp_path, new_env):
    # new_env: the refused reset asks for another step limit, so it builds a fresh env first
    async with Client(build_server(config(tmp_path, sim_size=(96, 72)))) as client:
        ok(await client.call_tool("sim_reset", {"scene": 0, "goal": "sofa", "seed": 2}))
        ok(await client.call_tool("sim_step", {"action": "turn_right"}))
        refused = await client.call_tool(
            "sim_reset", {"goal": "left of the chair", **({"max_steps": 1} if new_env else {})}
        )
        walked = ok(await client.call_tool("nav_step", {"actions": 2}))
        after = ok(await client.call_tool("sim_step", {"action": "turn_left"}))
    assert refused.is_error and "'left of the chair' is not in scene 0" in refused.content[0].text
    assert walked["steps"] == 3 and walked["goal"] == "sofa"
    assert after["steps"] == 4 and after["max_steps"] == 500 and after["status"] == "running"


async def test_a_walk_racing_a_reset_of_its_session_finishes_before_the_reset(tmp_path):
    import anyio

    server = build_server(config(tmp_path, sim_size=(96, 72)))
    async with Client(server) as client:
        ok(await client.call_tool("sim_reset", {"scene": 0, "goal": "sofa", "seed": 1}))
        results: dict[str, object] = {}

        async def walk() -> None:
            results["walk"] = await client.call_tool("nav_step", {"actions": 25})

        async def reset() -> None:
            await anyio.sleep(0.05)
            results["reset"] = await client.call_tool("sim_reset", {"scene": 0, "seed": 2})

        async with anyio.create_task_group() as tg:
            tg.start_soon(walk)
            tg.start_soon(reset)
        after = ok(await client.call_tool("sim_step", {"action": "turn_left"}))
    walked, fresh = ok(results["walk"]), ok(results["reset"])
    assert walked["steps"] == 25 and fresh["steps"] == 0  # the walk ran whole, then the reset
    assert after["steps"] == 1
