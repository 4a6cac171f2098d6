"""Every map tool through a real in-memory MCP client session, and every bad input of it."""

from __future__ import annotations

import base64
import dataclasses
import io
import json
from typing import Any

import cv2
import numpy as np
import pytest
from mcp import Client

from glmap_tools.app.frames import jpeg_base64, png_base64
from glmap_tools.server import build_server
from tests.test_server_fixtures import GROUPS, OBJECTS, config, counts, frame_args, view

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_the_server_lists_its_tools_with_read_only_hints_on_the_queries(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        tools = {t.name: t for t in (await client.list_tools()).tools}
    assert {"observe_frame", "find_instance", "find_region", "what_is_at"} <= set(tools)
    assert {"describe_unit", "map_summary", "new_map", "save_map", "load_map"} <= set(tools)
    for name in ("find_instance", "find_region", "what_is_at", "describe_unit", "map_summary"):
        assert tools[name].annotations.read_only_hint is True, name
    assert not tools["observe_frame"].annotations.read_only_hint
    top_k = tools["find_instance"].input_schema["properties"]["top_k"]
    assert (top_k["minimum"], top_k["maximum"]) == (1, 50)
    # Output schemas are left out of tools/list (token cost); results keep structured content.
    assert tools["find_instance"].output_schema is None
    assert "title" not in tools["find_instance"].input_schema
    assert tools["map_summary"].output_schema is None  # images travel without structure


async def test_an_observed_frame_reports_the_instances_and_the_region_it_added(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("observe_frame", frame_args())
        assert not result.is_error, result.content[0].text
        report = result.structured_content["report"]
        added = {c["text"]: c["global_id"] for c in report["instances_added"]}
        assert set(added) == {OBJECTS[1][1], OBJECTS[2][1], OBJECTS[3][1]}
        assert [r["text"] for r in report["regions_added"]] == [GROUPS[0]["description"]]
        assert result.structured_content["session"] == "default"
        assert await counts(client) == (1, 3, 1)


async def test_a_second_view_of_the_same_objects_merges_instead_of_adding(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("observe_frame", frame_args(eye=(0.4, -2.5, 1.4)))
        report = result.structured_content["report"]
        assert report["instances_added"] == []
        assert len(report["instances_merged"]) >= 2
        assert await counts(client) == (2, 3, 1)


async def test_find_instance_ranks_the_described_chair_first_with_its_geometry(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("find_instance", {"query": "blue office chair"})
        hits = result.structured_content["hits"]
        assert hits[0]["description"] == OBJECTS[3][1]
        assert hits[0]["score"] >= hits[-1]["score"]
        x, y, _ = hits[0]["centroid"]
        assert abs(x - -1.6) < 0.3 and abs(y - 0.4) < 0.3
        one = await client.call_tool("find_instance", {"query": "chair", "top_k": 1})
        assert len(one.structured_content["hits"]) == 1


@pytest.mark.parametrize(
    "embedder", ["hashing", pytest.param("minilm", marks=pytest.mark.slow)]
)  # hashing loads in the request; minilm loads on the background task
async def test_every_hit_carries_a_calibrated_match_flag_over_mcp(tmp_path, embedder):
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.language.minilm import MiniLMEmbedder
    from glmap_tools.map.queries import MATCH_RULES

    model = {"hashing": HashingEmbedder, "minilm": MiniLMEmbedder}[embedder]
    rules = MATCH_RULES.get(getattr(model, "name", ""), {})  # by what a query asks for
    tau = {k: rules.get(k, model.default_tau_match) for k in ("name", "region")}
    server = build_server(dataclasses.replace(config(tmp_path), embedder=embedder))
    async with Client(server) as client:
        await client.call_tool("observe_frame", frame_args())
        chair = await client.call_tool("find_instance", {"query": "a blue office chair"})
        bath = await client.call_tool("find_instance", {"query": "a white bathtub"})
        region = await client.call_tool("find_region", {"query": "dining corner"})
    for result, asks in ((chair, "name"), (bath, "name"), (region, "region")):
        for hit in result.structured_content["hits"]:
            assert hit["match"] is (hit["score"] >= tau[asks]), hit
    assert chair.structured_content["hits"][0]["match"] is True
    assert not any(h["match"] for h in bath.structured_content["hits"])


async def test_find_region_returns_the_region_with_its_member_instances(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        ids = observed.structured_content["report"]["local_to_global"]
        result = await client.call_tool("find_region", {"query": "dining corner"})
        (hit,) = result.structured_content["hits"]
        assert sorted(hit["instance_ids"]) == sorted([ids["1"], ids["2"]])


async def test_what_is_at_lists_the_chair_under_its_seat_nearest_first(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        observed = await client.call_tool("observe_frame", frame_args())
        chair = observed.structured_content["report"]["local_to_global"]["1"]
        result = await client.call_tool("what_is_at", {"x": 0.0, "y": 0.0, "radius": 0.1})
        units = result.structured_content["units"]
        assert chair in [u["id"] for u in units]
        assert all(u["id"] != 3 for u in units)  # the blue chair is 1.6 m away
        distances = [u["distance"] for u in units]
        assert distances == sorted(distances)
        between = await client.call_tool("what_is_at", {"x": 0.0, "y": -1.0, "radius": 0.0})
        assert between.structured_content["occupancy"] == "free"
        empty = await client.call_tool("what_is_at", {"x": 40.0, "y": 40.0})
        assert empty.structured_content["units"] == []
        assert empty.structured_content["occupancy"] == "unknown"


async def test_describe_unit_of_an_unknown_id_suggests_the_closest_one(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        known = await client.call_tool("describe_unit", {"id": 1})
        assert known.structured_content["id"] == 1
        result = await client.call_tool("describe_unit", {"id": 40})
        assert result.is_error
        assert "unit id 40 does not exist" in result.content[0].text
        assert "Did you mean '4'?" in result.content[0].text
        far = await client.call_tool("describe_unit", {"id": 900})
        assert "Closest id: 4." in far.content[0].text


async def test_map_summary_attaches_a_top_down_png_and_the_session_resources(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("map_summary", {})
    assert result.structured_content is None
    kinds = [c.type for c in result.content]
    assert kinds == ["text", "text", "image"]
    info = json.loads(result.content[0].text)
    assert info["summary"]["instances"] == 3
    assert "glmap://default/topdown.png" in info["resources"]
    image = cv2.imdecode(np.frombuffer(base64.b64decode(result.content[2].data), np.uint8), 1)
    assert image is not None and min(image.shape[:2]) > 16
    assert result.content[2].mime_type == "image/png"


async def test_files_given_by_absolute_path_build_the_same_map_as_base64(tmp_path):
    frame, ids = view((0.0, -2.6, 1.4))
    paths = {}
    for name, image in (("rgb", frame.rgb), ("depth", None), ("mask", ids.astype(np.uint8))):
        path = tmp_path / f"{name}.png"
        if name == "depth":
            image = (frame.depth * 1000).round().astype(np.uint16)
        path.write_bytes(base64.b64decode(png_base64(image)))
        paths[name] = str(path)
    args = frame_args()
    args["rgb"] = {"path": paths["rgb"]}
    args["depth"] = {"path": paths["depth"]}
    args["annotations"]["mask"] = {"path": paths["mask"]}
    async with Client(build_server(config(tmp_path))) as client:
        by_path = await client.call_tool("observe_frame", args)
    async with Client(build_server(config(tmp_path))) as client:
        by_value = await client.call_tool("observe_frame", frame_args())
    assert not by_path.is_error, by_path.content[0].text
    assert by_path.structured_content["report"] == by_value.structured_content["report"]


async def test_a_jpeg_colour_image_and_float_npy_depth_in_metres_are_accepted(tmp_path):
    frame, _ = view((0.0, -2.6, 1.4))
    buf = io.BytesIO()
    np.save(buf, frame.depth.astype(np.float32))
    args = frame_args()
    args["rgb"] = {"base64": "data:image/jpeg;base64," + jpeg_base64(frame.rgb)}
    args["depth"] = {"base64": base64.b64encode(buf.getvalue()).decode()}
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("observe_frame", args)
        assert not result.is_error, result.content[0].text
        assert await counts(client) == (1, 3, 1)


async def test_an_opengl_pose_in_a_y_up_world_lands_objects_where_the_opencv_pose_does(
    tmp_path,
):
    args = frame_args()
    m = np.array(args["pose"]["matrix"])
    gl = m.copy()
    gl[:3, :3] = m[:3, :3] @ np.diag([1.0, -1.0, -1.0])  # OpenCV -> OpenGL camera axes
    zup_from_yup = np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]])
    args["pose"] = {
        "matrix": (np.linalg.inv(zup_from_yup) @ gl).tolist(),
        "camera": "opengl",
        "world_up": "y",
    }
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", args)
        hits = await client.call_tool("find_instance", {"query": "red wooden chair"})
    x, y, _ = hits.structured_content["hits"][0]["centroid"]
    assert abs(x) < 0.25 and abs(y) < 0.25


def _set(args: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    node = args
    keys = path.split(".")
    for key in keys[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return args


_DELETE = object()
SMALL_RGB = png_base64(np.zeros((60, 80, 3), np.uint8))
GIF = base64.b64encode(b"GIF89a\x01\x00\x01\x00\x00\x00\x00;").decode()
BAD_INPUTS = [
    ("rgb.base64", "not base64 at all!!", "not valid base64"),
    ("rgb.base64", GIF, "not a PNG or JPEG"),
    ("rgb", {"base64": SMALL_RGB, "path": "/tmp/x.png"}, "exactly one of"),
    ("rgb.base64", SMALL_RGB, "rgb is 80x60 but depth is 160x120"),
    ("depth.base64", SMALL_RGB, "single-channel 16-bit PNG"),
    ("annotations.mask.base64", png_base64(np.zeros((60, 80), np.uint8)), "mask is 80x60"),
    ("pose.matrix", [[float("nan")] * 4] * 4, "NaN"),
    ("pose.matrix", [[2.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "not rigid"),
    ("pose.matrix", [[1.0, 0, 0], [0, 1, 0]], "4 rows of 4 numbers"),
    ("intrinsics", {"fx": 100.0}, "need fx, fy, cx and cy"),
    ("intrinsics.fx", -5.0, "positive finite focal length"),
    ("depth_scale", 0, "greater than 0"),
    ("annotations.objects", [{"id": 9, "label": "ghost"}], "mask of object 9"),
    ("annotations.groups", [{"id": 1, "description": "x", "members": [7]}], "unknown member"),
    ("rgb", {"path": "relative/rgb.png"}, "is relative"),
    ("rgb", {"path": "/nonexistent/rgb.png"}, "not a readable file"),
]


@pytest.mark.parametrize(("where", "value", "message"), BAD_INPUTS)
async def test_a_bad_observe_frame_input_is_a_tool_error_that_changes_nothing(
    tmp_path, where, value, message
):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        before = await counts(client)
        result = await client.call_tool("observe_frame", _set(frame_args(), where, value))
        assert result.is_error
        assert message in result.content[0].text
        assert await counts(client) == before
        again = await client.call_tool("find_instance", {"query": "chair"})  # still serving
        assert not again.is_error


async def test_a_frame_over_the_size_limit_is_refused_with_the_limit_stated(tmp_path):
    args = frame_args()
    async with Client(build_server(config(tmp_path, max_frame_bytes=4096))) as client:
        result = await client.call_tool("observe_frame", args)
        assert result.is_error
        text = result.content[0].text
        assert "limit for one frame" in text and "MiB" in text
        assert await counts(client) == (0, 0, 0)


async def test_an_image_over_the_pixel_limit_is_refused_before_it_is_decoded(tmp_path):
    async with Client(build_server(config(tmp_path, max_frame_pixels=10_000))) as client:
        result = await client.call_tool("observe_frame", frame_args())
    assert result.is_error
    assert "over the limit of 10000 pixels" in result.content[0].text


async def test_a_file_outside_the_allowed_roots_is_not_read(tmp_path):
    outside = tmp_path / "elsewhere.png"
    outside.write_bytes(base64.b64decode(SMALL_RGB))
    root = tmp_path / "frames"
    root.mkdir()
    async with Client(build_server(config(tmp_path, file_roots=(root,)))) as client:
        result = await client.call_tool(
            "observe_frame", _set(frame_args(), "rgb", {"path": str(outside)})
        )
    assert result.is_error
    assert "outside the folders this server may read" in result.content[0].text


@pytest.mark.parametrize(
    ("tool", "args", "message"),
    [
        ("find_instance", {"query": ""}, "at least 1 character"),
        ("find_instance", {"query": "chair", "top_k": 0}, "greater than or equal to 1"),
        ("find_region", {"query": "x", "top_k": 51}, "less than or equal to 50"),
        ("what_is_at", {"x": 0, "y": 0, "radius": 9}, "less than or equal to 5"),
        ("describe_unit", {"id": 0}, "greater than or equal to 1"),
        ("find_instance", {"query": "chair", "session": "nope"}, "session 'nope' does not exist"),
    ],
)
async def test_out_of_bounds_query_arguments_are_tool_errors_naming_the_bound(
    tmp_path, tool, args, message
):
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool(tool, args)
    assert result.is_error
    assert message in result.content[0].text


@pytest.mark.parametrize("size", [(1, 1), (37, 5), (640, 480), (1023, 767)])
def test_image_sizes_read_from_the_headers_match_the_decoded_images(size):
    from glmap_tools.app.images import image_header

    w, h = size
    rng = np.random.default_rng(w * h)
    rgb = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    grey16 = rng.integers(0, 65535, (h, w), dtype=np.uint16)
    for encoded in (
        base64.b64decode(png_base64(rgb)),
        base64.b64decode(png_base64(grey16)),
        base64.b64decode(jpeg_base64(rgb)),
    ):
        _, hw, hh, _, _ = image_header(encoded)
        decoded = cv2.imdecode(np.frombuffer(encoded, np.uint8), cv2.IMREAD_UNCHANGED)
        assert (hw, hh) == (decoded.shape[1], decoded.shape[0])


@pytest.mark.parametrize(
    ("where", "label", "description"),
    [("label", "chair\x00\x1b[2J", "a chair"), ("description", "chair", "a chair\x1b[2J")],
)
async def test_control_characters_in_annotations_are_refused_naming_the_field(
    tmp_path, where, label, description
):
    # Issue 27 item 6: "\x00\x1b[2J" was stored and shown to every client.
    args = frame_args()
    args["annotations"]["objects"][0].update(label=label, description=description)
    async with Client(build_server(config(tmp_path))) as client:
        res = await client.call_tool("observe_frame", args)
        assert res.is_error
        text = res.content[0].text
        assert f"objects.0.{where}" in text and "control characters" in text, text
        assert await counts(client) == (0, 0, 0)


async def test_a_search_of_an_empty_map_says_why_and_how_per_call_clients_keep_one(tmp_path):
    """A per-call client (a new server process per tool call) meets an empty map each time:
    the result says so and names both fixes."""
    async with Client(build_server(config(tmp_path))) as client:
        empty = [
            await client.call_tool(t, {"query": "a bed"}) for t in ("find_instance", "find_region")
        ]
        await client.call_tool("observe_frame", frame_args())
        seen = await client.call_tool("find_region", {"query": "a rocket launch pad"})
    for result in empty:
        text = result.content[0].text
        assert "hits: none" in text and "--map NAME" in text and "client.session" in text
        assert result.structured_content["note"] in text
    assert "note:" not in seen.content[0].text and seen.structured_content["note"] == ""
