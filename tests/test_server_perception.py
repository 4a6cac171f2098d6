"""observe_frame without annotations and label_segments, over a real in-memory MCP session."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from mcp import Client

from glmap_tools.app.frames import observe_arguments
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, counts, view

pytestmark = pytest.mark.anyio
EYE = (0.0, -2.6, 1.4)


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def _unannotated() -> tuple[dict[str, Any], np.ndarray]:
    frame, ids = view(EYE, 320, 240)
    return observe_arguments(frame), ids


def _owner(segment: dict[str, Any], ids: np.ndarray) -> int:
    """The ground-truth object most of a segment's image box shows (test-side naming)."""
    r0, c0, r1, c1 = segment["box"]
    values, n = np.unique(ids[r0:r1, c0:c1], return_counts=True)
    n[values == 0] = 0
    return int(values[np.argmax(n)])


async def _observe(client: Client) -> tuple[dict[str, Any], dict[int, int]]:
    args, ids = _unannotated()
    result = await client.call_tool("observe_frame", args)
    assert not result.is_error, result.content[0].text
    pending = result.structured_content["pending"]
    owners = {s["id"]: _owner(s, ids) for s in pending["segments"]}
    return result, owners


async def test_an_unannotated_frame_is_labelled_by_the_agent_and_found_by_find_instance(
    tmp_path,
):
    async with Client(build_server(config(tmp_path))) as client:
        result, owners = await _observe(client)
        assert [c.type for c in result.content] == ["text", "image"]
        assert await counts(client) == (1, 0, 0)  # geometry and occupancy only
        by_object = {o: s for s, o in owners.items()}
        assert {1, 2, 3} <= set(by_object), owners
        labels = [
            {"segments": [by_object[3]], "label": "chair", "description": "a blue office chair"},
            {"segments": [by_object[2]], "label": "table", "description": "a dining table"},
            {"segments": [by_object[1]], "label": "ignore"},
        ]
        groups = [{"members": [by_object[3], by_object[2]], "description": "a study corner"}]
        frame_id = result.structured_content["pending"]["frame"]
        done = await client.call_tool(
            "label_segments", {"frame": frame_id, "labels": labels, "groups": groups}
        )
        assert not done.is_error, done.content[0].text
        assert len(done.structured_content["report"]["instances_added"]) == 2
        _, instances, regions = await counts(client)
        assert (instances, regions) == (2, 1)
        hits = await client.call_tool("find_instance", {"query": "blue office chair", "top_k": 1})
        hit = hits.structured_content["hits"][0]
        assert hit["label"] == "chair"
        assert abs(hit["centroid"][0] - -1.6) < 0.3 and abs(hit["centroid"][1] - 0.4) < 0.3


@pytest.mark.parametrize(
    ("labels", "words"),
    [
        ([{"segments": [999], "label": "chair"}], "segment 999"),
        ([{"segments": [1], "label": "chair"}, {"segments": [1], "label": "seat"}], "twice"),
        ([{"segments": [1], "label": " "}], "empty label"),
    ],
)
async def test_bad_labels_are_refused_and_leave_the_map_and_the_pending_frame_as_they_were(
    tmp_path, labels, words
):
    async with Client(build_server(config(tmp_path))) as client:
        result, _ = await _observe(client)
        frame_id = result.structured_content["pending"]["frame"]
        bad = await client.call_tool("label_segments", {"frame": frame_id, "labels": labels})
        assert bad.is_error and words in bad.content[0].text
        assert await counts(client) == (1, 0, 0)
        ok = await client.call_tool(
            "label_segments", {"frame": frame_id, "labels": [{"segments": [1], "label": "thing"}]}
        )
        assert not ok.is_error, ok.content[0].text
        assert (await counts(client))[1] == 1


async def test_an_unknown_or_already_labelled_frame_says_which_frames_wait(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result, _ = await _observe(client)
        frame_id = result.structured_content["pending"]["frame"]
        unknown = await client.call_tool(
            "label_segments", {"frame": "f999", "labels": [{"segments": [1], "label": "x"}]}
        )
        assert unknown.is_error
        assert "no frame has that id" in unknown.content[0].text
        assert frame_id in unknown.content[0].text
        labels = {"frame": frame_id, "labels": [{"segments": [1], "label": "ignore"}]}
        first = await client.call_tool("label_segments", labels)
        assert not first.is_error and "nothing added" in first.structured_content["summary"]
        again = await client.call_tool("label_segments", labels)
        assert again.is_error and "already labelled" in again.content[0].text


async def test_a_new_map_expires_the_pending_frames_of_the_old_one(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result, _ = await _observe(client)
        frame_id = result.structured_content["pending"]["frame"]
        fresh = await client.call_tool("new_map", {})
        assert not fresh.is_error, fresh.content[0].text
        late = await client.call_tool(
            "label_segments", {"frame": frame_id, "labels": [{"segments": [1], "label": "chair"}]}
        )
        assert late.is_error and "replaced" in late.content[0].text
        assert await counts(client) == (0, 0, 0)


async def test_the_observe_reply_lists_segment_bounds_in_metres(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result, owners = await _observe(client)
        pending = result.structured_content["pending"]
        table = next(s for s in pending["segments"] if owners[s["id"]] == 2)
        assert f"frame={pending['frame']}" in result.content[0].text
        assert table["hi"][2] == pytest.approx(0.75, abs=0.05)
        assert table["lo"][0] < 1.4 < table["hi"][0]


async def test_an_unannotated_frame_without_valid_depth_is_refused_and_nothing_waits(tmp_path):
    from glmap_tools.geometry.frame import RGBDFrame

    frame, _ = view(EYE, 320, 240)
    empty = RGBDFrame(frame.rgb, frame.depth * 0, frame.intrinsics, frame.pose)
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("observe_frame", observe_arguments(empty))
        assert result.is_error and "no valid pixel" in result.content[0].text
        assert await counts(client) == (0, 0, 0)
        late = await client.call_tool(
            "label_segments", {"frame": "f1", "labels": [{"segments": [1], "label": "chair"}]}
        )
        assert late.is_error and "Pending frames: none" in late.content[0].text


async def test_a_frame_past_the_pending_memory_cap_is_refused_and_changes_nothing(
    tmp_path, monkeypatch
):
    # Issue 27 item 2: pending frames had no byte cap (two sessions took a server to 5 GB).
    from glmap_tools.perception import pending

    args, ids = _unannotated()
    monkeypatch.setattr(pending, "MAX_SERVER_PENDING_BYTES", ids.size * 8 * 3 // 2, raising=False)
    async with Client(build_server(config(tmp_path))) as client:
        first = await client.call_tool("observe_frame", args)
        assert not first.is_error, first.content[0].text
        before = await counts(client)
        second = await client.call_tool("observe_frame", args)
        assert second.is_error
        assert "would pass its cap of" in second.content[0].text
        assert "label_segments" in second.content[0].text
        assert await counts(client) == before  # refused before the geometry went in
        frame_id = first.structured_content["pending"]["frame"]
        labelled = await client.call_tool(
            "label_segments", {"frame": frame_id, "labels": [{"segments": [1], "label": "x"}]}
        )
        assert not labelled.is_error, labelled.content[0].text
        third = await client.call_tool("observe_frame", args)  # room again
        assert not third.is_error, third.content[0].text


async def test_control_characters_in_a_segment_label_are_refused_naming_the_field(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        result, _ = await _observe(client)
        frame_id = result.structured_content["pending"]["frame"]
        bad = {"frame": frame_id, "labels": [{"segments": [1], "label": "chair\x1b[2J"}]}
        res = await client.call_tool("label_segments", bad)
        assert res.is_error and "labels.0.label" in res.content[0].text
        assert "control characters" in res.content[0].text
