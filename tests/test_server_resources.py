"""glmap:// resources and progress notifications, through an in-memory client session."""

from __future__ import annotations

import base64
import json

import cv2
import numpy as np
import pytest
from mcp import Client
from mcp.shared.exceptions import MCPError

from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_the_server_lists_saved_maps_and_the_per_session_templates(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("save_map", {"name": "one"})
        resources = (await client.list_resources()).resources
        templates = (await client.list_resource_templates()).resource_templates
        maps = await client.read_resource("glmap://maps")
    assert [str(r.uri) for r in resources] == ["glmap://maps"]
    assert json.loads(maps.contents[0].text) == ["one"]
    uris = {t.uri_template for t in templates}
    assert {
        "glmap://{session}/summary",
        "glmap://{session}/instances/{unit_id}",
        "glmap://{session}/regions/{unit_id}",
        "glmap://{session}/topdown.png",
    } <= uris


async def test_the_current_session_resources_show_its_summary_units_and_top_down_image(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        ids = observed.structured_content["report"]["local_to_global"]
        region_id = observed.structured_content["report"]["regions_added"][0]["global_id"]
        summary = json.loads(
            (await client.read_resource("glmap://current/summary")).contents[0].text
        )
        by_handle = await client.read_resource("glmap://default/summary")
        index = json.loads(
            (await client.read_resource("glmap://current/instances")).contents[0].text
        )
        chair = await client.read_resource(f"glmap://current/instances/{ids['1']}")
        region = await client.read_resource(f"glmap://current/regions/{region_id}")
        image = await client.read_resource("glmap://current/topdown.png")
    assert (summary["instances"], summary["regions"], summary["frames"]) == (3, 1, 1)
    assert json.loads(by_handle.contents[0].text) == summary
    assert sorted(u["id"] for u in index) == sorted(ids.values())
    assert json.loads(chair.contents[0].text)["description"] == "a red wooden chair"
    assert sorted(json.loads(region.contents[0].text)["instance_ids"]) == sorted(
        [ids["1"], ids["2"]]
    )
    assert image.contents[0].mime_type == "image/png"
    png = np.frombuffer(base64.b64decode(image.contents[0].blob), np.uint8)
    assert cv2.imdecode(png, cv2.IMREAD_COLOR) is not None


@pytest.mark.parametrize(
    ("uri", "message"),
    [
        ("glmap://current/instances/99", "does not exist"),
        ("glmap://current/instances/chair", "is not an integer"),
        ("glmap://nosuchsession/summary", "session 'nosuchsession' does not exist"),
    ],
)
async def test_a_missing_resource_is_an_error_that_says_what_exists(tmp_path, uri, message):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        with pytest.raises(MCPError) as err:
            await client.read_resource(uri)
    assert message in str(err.value)


async def test_observe_frame_reports_progress_in_order_until_done(tmp_path):
    updates: list[tuple[float, float | None, str | None]] = []

    async def on_progress(progress: float, total: float | None, message: str | None) -> None:
        updates.append((progress, total, message))

    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool(
            "observe_frame", frame_args(), progress_callback=on_progress
        )
    assert not result.is_error
    assert [p for p, _, _ in updates] == sorted(p for p, _, _ in updates)
    assert updates[0][0] == 0 and updates[-1][:2] == (3, 3)
    assert any("fusing 3 objects" in (m or "") for _, _, m in updates)
