"""render_view and the top-down image through an in-memory client: each target, the camera
it reports and how it was chosen, what the images show, bad requests."""

from __future__ import annotations

import base64

import cv2
import numpy as np
import pytest
from mcp import Client
from mcp.shared.exceptions import MCPError

from glmap_tools.app.inputs import (
    AnnotationInput,
    FileInput,
    IntrinsicsInput,
    PoseInput,
    decode_frame,
)
from glmap_tools.app.views import ViewRequest, render_request
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.map.occupancy import OccupancyGrid
from glmap_tools.server import ServerConfig, build_server
from glmap_tools.views.topdown import palette
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
            result = await client.call_tool(
                "render_view", {"target": "instance", "unit_id": uid, "context": False}
            )
            (image,) = images(result)
            rows, cols = np.nonzero(drawn(image))
            h, w = drawn(image).shape
            assert len(rows) > 0.02 * h * w, local
            assert abs(rows.mean() - h / 2) < h / 4 and abs(cols.mean() - w / 2) < w / 4, local


async def test_an_instance_view_reports_how_its_camera_was_selected(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        report = observed.structured_content["report"]
        chair = report["local_to_global"]["1"]
        region = report["regions_added"][0]["global_id"]
        seen = await client.call_tool("render_view", {"target": "instance", "unit_id": chair})
        alone = await client.call_tool(
            "render_view", {"target": "instance", "unit_id": chair, "context": False}
        )
        group = await client.call_tool("render_view", {"target": "region", "unit_id": region})
    text = seen.content[0].text
    first, selection = text.splitlines()[:2]
    assert first.startswith(f"instance {chair} (chair): camera at (")
    assert "0.88) m" in first  # the agent's eye height above the floor (z = 0)
    assert selection.startswith(f"view selection: instance {chair} (chair): chose 1 of ")
    assert "candidate cameras (in seen-free space)" in selection
    assert "of its Gaussians visible" in selection and "FALLBACK" not in text
    assert "Drawn: the whole map from that camera" in selection
    assert "Drawn: the unit's own Gaussians only" in alone.content[0].text
    assert f"view selection: region {region}: chose 1 of " in group.content[0].text


def centre(image: np.ndarray) -> np.ndarray:
    """[h, w, 3] int: the middle third of the image in both directions."""
    h, w = image.shape[:2]
    return image[h // 3 : 2 * h // 3, w // 3 : 2 * w // 3].astype(int)


async def test_an_instance_view_in_context_shows_that_instance_at_the_centre(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        ids = observed.structured_content["report"]["local_to_global"]
        red = await client.call_tool("render_view", {"target": "instance", "unit_id": ids["1"]})
        blue = await client.call_tool("render_view", {"target": "instance", "unit_id": ids["3"]})
    (red_image,) = images(red)
    (blue_image,) = images(blue)
    for image, (hue, other) in ((red_image, (0, 2)), (blue_image, (2, 0))):
        middle = centre(image)
        assert drawn(middle).mean() > 0.25  # the middle is mostly drawn, not background
        own = (middle[..., hue] > middle[..., other] + 60).mean()
        wrong = (middle[..., other] > middle[..., hue] + 60).mean()
        assert own > 0.2 and wrong < 0.01, (own, wrong)  # the red chair, not the blue one


def test_a_view_from_unobserved_space_is_flagged_as_a_fallback_in_the_text():
    glmap = GLMap(MapConfig(voxel_size=0.04), embedder=HashingEmbedder())
    observed = frame_args()
    frame, semantics = decode_frame(
        FileInput(**observed["rgb"]),
        FileInput(**observed["depth"]),
        1000.0,
        IntrinsicsInput(**observed["intrinsics"]),
        PoseInput(**observed["pose"]),
        AnnotationInput(**observed["annotations"]),
        ServerConfig(),
    )
    report = glmap.integrate(frame, semantics)
    glmap.occupancy = OccupancyGrid(glmap.config.cell_size)  # as if no free space was seen
    chair = report.local_to_global[1]
    rendered = render_request(glmap, ViewRequest("instance", (64, 48), unit_id=chair))
    assert len(rendered.views) == 1
    assert "(FALLBACK: no seen-free viewpoint" in rendered.notes[0]
    assert "The FALLBACK camera is not in space seen to be free" in rendered.notes[1]


async def test_the_whole_map_is_seen_from_above_at_an_angle(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("render_view", {"target": "map"})
    text = result.content[0].text
    assert text.startswith("whole map: camera at (") and "pitch 50 deg down" in text
    (image,) = images(result)
    assert drawn(image).mean() > 0.02


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


@pytest.mark.parametrize(
    "args",
    [
        {"target": "map"},
        {"target": "instance", "unit_id": 1},
        {"target": "region", "unit_id": 1},
        {"target": "situated", "x": 0.0, "y": 0.0},
        {"target": "pose", "pose": frame_args()["pose"]},
    ],
)
async def test_rendering_an_empty_map_says_to_observe_first(tmp_path, args):
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("render_view", args)
    assert result.is_error
    assert "the map is empty; observe frames" in result.content[0].text


async def test_the_top_down_image_of_an_empty_map_is_left_out_with_the_reason(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        summary = await client.call_tool("map_summary", {})
        with pytest.raises(MCPError, match="the map is empty; observe frames"):
            await client.read_resource("glmap://current/topdown.png")
    assert not summary.is_error
    assert images(summary) == []
    assert "No top-down image yet: the map is empty" in summary.content[1].text


async def test_the_top_down_image_outlines_regions_and_marks_the_latest_camera(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        ids = observed.structured_content["report"]["local_to_global"]
        summary = await client.call_tool("map_summary", {})
    legend = summary.content[1].text
    assert "+x right, +y up" in legend and "Outlines labelled R<id> = region hulls" in legend
    assert "Red arrow = the agent at (0.00, -2.60)" in legend
    assert "The agent is the camera of the latest frame." in legend
    (image,) = images(summary)
    for uid in ids.values():  # each instance's footprint is drawn in its own colour
        assert np.all(image == palette(uid), axis=2).any(), uid
