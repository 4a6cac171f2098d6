"""render_view through an in-memory client: each target, the camera it reports, bad requests."""

from __future__ import annotations

import base64

import cv2
import numpy as np
import pytest
from mcp import Client

from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def images(result) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    out = []
    for block in result.content:
        if block.type == "image":
            data = np.frombuffer(base64.b64decode(block.data), np.uint8)
            out.append(cv2.cvtColor(cv2.imdecode(data, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB))
    return out


def drawn(image: np.ndarray) -> np.ndarray:
    """[H, W] bool: pixels that are not the white background."""
    return np.any(image < 245, axis=2)


async def test_every_render_target_returns_images_and_the_camera_it_used(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        report = observed.structured_content["report"]
        chair = report["local_to_global"]["1"]
        region = report["regions_added"][0]["global_id"]
        pose = frame_args()["pose"]
        requests = {
            "instance": {"target": "instance", "unit_id": chair},
            "region": {"target": "region", "unit_id": region},
            "map": {"target": "map", "width": 96, "height": 64},
            "pose": {"target": "pose", "pose": pose},
            "situated": {"target": "situated", "x": 0.0, "y": -2.0, "heading_deg": 90},
        }
        results = {k: await client.call_tool("render_view", v) for k, v in requests.items()}
    for name, result in results.items():
        assert not result.is_error, (name, result.content[0].text)
        assert result.structured_content is None  # images travel without structure
        assert "camera at (" in result.content[0].text
    assert [img.shape for img in images(results["map"])] == [(64, 96, 3)]
    assert len(images(results["situated"])) == 4
    text = results["situated"].content[0].text
    assert [line.split(":")[0] for line in text.splitlines()[:4]] == [
        "front",
        "left",
        "back",
        "right",
    ]
    assert "heading 90 deg" in text and "heading 180 deg" in text
    assert "camera at (0.00, -2.00, 0.88) m" in text  # agent eye height above the floor
    front = images(results["situated"])[0]
    assert drawn(front).mean() > 0.02  # facing the objects from in front of them
    assert drawn(images(results["situated"])[2]).mean() < 0.001  # nothing mapped behind


async def test_an_instance_view_puts_the_instance_in_the_middle_of_the_image(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        for local in ("1", "2", "3"):
            uid = observed.structured_content["report"]["local_to_global"][local]
            result = await client.call_tool("render_view", {"target": "instance", "unit_id": uid})
            (image,) = images(result)
            rows, cols = np.nonzero(drawn(image))
            h, w = drawn(image).shape
            assert len(rows) > 0.02 * h * w, local
            assert abs(rows.mean() - h / 2) < h / 4 and abs(cols.mean() - w / 2) < w / 4, local


async def test_a_view_from_the_observing_pose_looks_like_the_observed_frame(tmp_path):
    args = frame_args()
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", args)
        result = await client.call_tool(
            "render_view", {"target": "pose", "pose": args["pose"], "width": 160, "height": 120}
        )
    (image,) = images(result)
    mask = base64.b64decode(args["annotations"]["mask"]["base64"])
    objects = cv2.imdecode(np.frombuffer(mask, np.uint8), cv2.IMREAD_UNCHANGED) > 0
    overlap = (drawn(image) & objects).sum() / objects.sum()
    assert overlap > 0.6


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ({"target": "instance"}, "needs unit_id"),
        ({"target": "region", "unit_id": 1}, "is an instance; use target='instance'"),
        ({"target": "instance", "unit_id": 4}, "is a region; use target='region'"),
        ({"target": "instance", "unit_id": 99}, "does not exist"),
        ({"target": "situated", "x": 1.0}, "needs x and y"),
        ({"target": "pose"}, "needs pose="),
        ({"target": "pose", "pose": {"matrix": [[None] * 4] * 4}}, "NaN, infinity or null"),
        ({"target": "photo"}, "Input should be 'instance'"),
        ({"target": "map", "width": 5000}, "less than or equal to 1024"),
    ],
)
async def test_a_bad_render_request_is_a_tool_error_saying_what_to_give(tmp_path, args, message):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("render_view", args)
    assert result.is_error
    assert message in result.content[0].text


async def test_rendering_an_empty_map_says_to_observe_first(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("render_view", {"target": "map"})
    assert result.is_error
    assert "the map is empty; observe frames" in result.content[0].text
