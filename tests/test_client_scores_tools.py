"""Navigation tools without surprises: progress notifications through a real client session,
walked_m as the path length, bearing relative to the heading."""

from __future__ import annotations

import json
import math
import os

import pytest
from mcp import Client

from glmap_tools.server import build_server
from glmap_tools.worlds.splits import load_split
from tests.test_server_fixtures import config

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio
EPISODE = load_split("tune", "objectnav")[0].episode_id


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def ok(result) -> dict:  # type: ignore[no-untyped-def, type-arg]
    assert not result.is_error, result.content[0].text
    return json.loads(result.content[0].text)


async def test_nav_step_navigate_to_and_look_around_send_progress_notifications(tmp_path):
    seen: dict[str, list[tuple[float, float | None, str | None]]] = {}

    def on(tool: str):  # type: ignore[no-untyped-def]
        async def progress(done: float, total: float | None, message: str | None) -> None:
            seen.setdefault(tool, []).append((done, total, message))

        return progress

    server = build_server(config(tmp_path, sim_size=(96, 72)))
    async with Client(server) as client:
        ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        turned = ok(await client.call_tool("look_around", {}, progress_callback=on("look_around")))
        args = {"policy": "frontier", "actions": 4}
        stepped = ok(await client.call_tool("nav_step", args, progress_callback=on("nav_step")))
        front = ok(await client.call_tool("frontiers", {"top_k": 1}))["frontiers"][0]
        goal = {"x": front["xy"][0], "y": front["xy"][1], "max_steps": 3}
        walk = ok(await client.call_tool("navigate_to", goal, progress_callback=on("navigate_to")))
    assert turned["steps"] == 12
    looked = seen["look_around"]
    assert [p for p, _, _ in looked] == list(range(13)) and looked[-1][1] == 12
    steps = sum(stepped["actions"].values())
    assert len(seen["nav_step"]) >= steps + 1 and seen["nav_step"][0][2] == "nav_step 1/4"
    assert seen["nav_step"][-1][0] == 4 and seen["nav_step"][-1][2] == stepped["outcome"]
    assert len(seen["navigate_to"]) == walk["walk_steps"] + 1
    assert seen["navigate_to"][-1][2] == walk["outcome"]
    dones = [p for p, _, _ in seen["navigate_to"]]
    assert dones == sorted(dones)  # progress only grows


async def test_walked_m_is_the_length_of_the_path_not_the_straight_line(tmp_path):
    server = build_server(config(tmp_path, sim_size=(96, 72)))
    async with Client(server) as client:
        start = ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        args = {"policy": "frontier", "actions": 40, "details": True}
        stepped = ok(await client.call_tool("nav_step", args))
    points = [start["position"]] + [d["position"] for d in stepped["decisions"]]
    path = sum(math.dist(a, b) for a, b in zip(points, points[1:], strict=False))
    straight = math.dist(points[0], points[-1])
    assert "moved_m" not in stepped
    assert stepped["walked_m"] == pytest.approx(path, abs=0.05)
    assert stepped["actions"].get("move_forward", 0) * 0.25 >= stepped["walked_m"] - 1e-6
    assert path > straight + 0.25  # the frontier walk turned: the two differ here


async def test_bearing_is_described_as_relative_to_the_heading(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        tools = {t.name: t for t in (await client.list_tools()).tools}
    assert "bearing_deg: from the heading, + = left" in str(tools["frontiers"].description)
    from glmap_tools.app.tools_map import FromAgent

    field = FromAgent.model_fields["bearing_deg"]
    assert field.description == "degrees from the agent's heading, + = to its left"


async def test_locate_situation_names_the_fields_of_each_nearby_unit(tmp_path):
    from agents.sqa import context_notes
    from tests.test_server_fixtures import frame_args

    async with Client(build_server(config(tmp_path))) as client:
        for eye in ((0.0, -2.6, 1.4), (-2.5, 1.5, 1.4)):
            assert not (await client.call_tool("observe_frame", frame_args(eye))).is_error
        args = {"situation": "I am standing next to the dining table, facing the blue chair"}
        info = ok(await client.call_tool("locate_situation", args))
    nearby = info["around"]["nearby"]
    assert nearby and all(
        list(n) == ["id", "label", "distance_m", "bearing_deg", "direction"] for n in nearby
    )
    assert [n["distance_m"] for n in nearby] == sorted(n["distance_m"] for n in nearby)
    front = [n for n in nearby if n["direction"] == "front"]
    assert all(-45 <= n["bearing_deg"] < 45 for n in front)
    notes = context_notes(info, ids=True)  # the SQA agent reads the named fields
    first = nearby[0]
    assert f"{first['label']} ({first['distance_m']} m, id {first['id']})" in notes


def test_the_match_threshold_depends_on_what_a_query_asks_for():
    from glmap_tools.map.queries import MATCH_RULES, match_threshold, query_kind

    class Embedder:
        name = "all-MiniLM-L6-v2"
        default_tau_match = 0.49

    class Map:
        embedder = Embedder()

    assert query_kind("instance", "desk") == "name"
    assert query_kind("instance", "somewhere to sit") == "use"
    assert query_kind("region", "a place to eat") == "region"
    rules = MATCH_RULES["all-MiniLM-L6-v2"]
    # "desk" reached a chair at 0.497: no match by name; a region needs less than an instance.
    assert match_threshold(Map(), "instance", "desk") == rules["name"] > 0.497  # type: ignore[arg-type]
    assert rules["region"] < rules["use"] <= 0.49 < rules["name"]
    Embedder.name = "hashing-256"  # not calibrated per kind: its one threshold
    assert match_threshold(Map(), "region", "kitchen") == 0.49  # type: ignore[arg-type]
