"""locate_situation through a real in-memory MCP client session."""

from __future__ import annotations

import json

import pytest
from mcp import Client

from glmap_tools.server import build_server
from tests.test_server_fixtures import config, counts, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_a_situation_comes_back_as_a_pose_a_heat_map_and_four_captioned_views(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        for eye in ((0.0, -2.6, 1.4), (-2.5, 1.5, 1.4)):
            assert not (await client.call_tool("observe_frame", frame_args(eye))).is_error
        before = await counts(client)
        result = await client.call_tool(
            "locate_situation",
            {
                "situation": "I am standing next to the dining table, facing the blue chair",
                "question": "Can I reach the blue chair by walking straight ahead?",
            },
        )
        assert not result.is_error, result.content[0].text
        info = json.loads(result.content[0].text)
        assert await counts(client) == before  # read-only
    sit = info["situation"]
    assert {"x", "y", "heading_deg", "confidence", "anchors", "facing"} <= set(sit)
    assert sit["facing_text"] == "the blue chair"
    assert sit["reading"]["anchor"] == "dining table" and sit["reading"]["facing"] == "blue chair"
    # The blue chair stands at (-1.6, 0.4): the pose faces it.
    assert [v[0] for v in info["views"]] == ["front", "left", "back", "right"]
    assert info["map_answer"]["type"] == "reach" and info["map_answer"]["answer"] == "yes"
    images = [c for c in result.content if c.type == "image"]
    assert len(images) == 2 and all(c.mime_type == "image/png" for c in images)


async def test_topdown_adds_a_map_crop_with_unit_ids_around_the_pose(tmp_path):
    import base64

    import cv2
    import numpy as np

    async with Client(build_server(config(tmp_path))) as client:
        for eye in ((0.0, -2.6, 1.4), (-2.5, 1.5, 1.4)):
            assert not (await client.call_tool("observe_frame", frame_args(eye))).is_error
        args = {"situation": "I am standing next to the dining table, facing the blue chair"}
        result = await client.call_tool("locate_situation", {**args, "topdown": True})
        assert not result.is_error, result.content[0].text
    images = [c for c in result.content if c.type == "image"]
    texts = " ".join(c.text for c in result.content if c.type == "text")
    assert len(images) == 3 and "top-down crop" in texts
    crop = cv2.imdecode(np.frombuffer(base64.b64decode(images[2].data), np.uint8), 1)
    assert crop.shape[0] == crop.shape[1] <= 384  # 6 m around the pose, north up
    red = (crop[..., 2] > 180) & (crop[..., 1] < 80) & (crop[..., 0] < 80)  # the agent arrow
    rows, cols = np.nonzero(red)
    centre = crop.shape[0] / 2
    assert abs(rows.mean() - centre) < 0.15 * centre and abs(cols.mean() - centre) < 0.15 * centre


async def test_a_situation_on_an_empty_map_or_matching_nothing_is_a_clear_error(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        empty = await client.call_tool("locate_situation", {"situation": "by the bed"})
        assert empty.is_error and "the map is empty" in empty.content[0].text
        await client.call_tool("observe_frame", frame_args())
        none = await client.call_tool(
            "locate_situation", {"situation": "in the garage facing the car"}
        )
        assert none.is_error and "nothing in the map matches" in none.content[0].text


async def test_a_callers_own_reading_is_used_and_comes_back_for_correction(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        for eye in ((0.0, -2.6, 1.4), (-2.5, 1.5, 1.4)):
            assert not (await client.call_tool("observe_frame", frame_args(eye))).is_error
        reading = {
            "anchor": "dining table",
            "facing": None,
            "constraints": [{"object": "blue chair", "clock": 12}],
        }
        result = await client.call_tool("locate_situation", {"reading": reading})
        assert not result.is_error, result.content[0].text
        sit = json.loads(result.content[0].text)["situation"]
        assert sit["reading"]["constraints"] == [
            {"object": "blue chair", "side": None, "clock": 12}
        ]
        assert any("scored against 'blue chair' at 0 deg" in n for n in sit["notes"])
        bad = await client.call_tool(
            "locate_situation", {"reading": {"constraints": [{"object": "lamp"}]}}
        )
        assert bad.is_error and "exactly one of side" in bad.content[0].text
        none = await client.call_tool("locate_situation", {})
        assert none.is_error and "or a reading" in none.content[0].text
