"""Property tests: thousands of random and malformed tool calls against an in-memory server.

Whatever the arguments, every call returns in bounded time, failures are tool errors with
a message (never a crash), a rejected frame leaves the map as it was, the maps folder only
ever holds complete map and PLY files, and the server keeps serving.
"""

from __future__ import annotations

import base64
import copy
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import anyio
import anyio.from_thread
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcp import Client

from glmap_tools.app.frames import png_base64
from glmap_tools.gaussians.ply import read_ply
from glmap_tools.map.store import MapStore
from glmap_tools.server import build_server
from glmap_tools.server.build import BUG_NOTE
from tests.test_server_fixtures import config, frame_args

CALL_TIMEOUT = 30.0
EXAMPLES = 600  # x 1-6 calls each: about 3000 calls
TOOLS = [
    "observe_frame",
    "find_instance",
    "find_region",
    "what_is_at",
    "describe_unit",
    "map_summary",
    "new_map",
    "save_map",
    "load_map",
    "list_maps",
    "render_view",
    "export_ply",
    "sim_step",
    "sim_reset",
    "no_such_tool",
]
VALID_FRAME = frame_args(eye=(0.0, -2.6, 1.4), width=80, height=60)
FRAME_PATHS = [
    "rgb",
    "rgb.base64",
    "rgb.path",
    "depth",
    "depth.base64",
    "depth_scale",
    "intrinsics",
    "intrinsics.fx",
    "intrinsics.hfov_deg",
    "pose",
    "pose.matrix",
    "pose.camera",
    "pose.world_up",
    "annotations",
    "annotations.mask",
    "annotations.mask.base64",
    "annotations.objects",
    "annotations.groups",
    "session",
    "unexpected",
]

json_leaf = (
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=24)
)
json_value = st.recursive(
    json_leaf,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=10,
)
png = base64.b64decode(VALID_FRAME["rgb"]["base64"])
base64_junk = st.one_of(
    st.binary(max_size=96).map(lambda b: base64.b64encode(b).decode()),
    st.integers(8, len(png) - 1).map(lambda n: base64.b64encode(png[:n]).decode()),
    st.binary(min_size=1, max_size=32).map(
        lambda b: base64.b64encode(png[:33] + b + png[33:]).decode()
    ),
    st.just(png_base64(np.zeros((1000, 1000), np.uint8))),  # over the pixel limit
    st.text(max_size=40),
)
names = st.one_of(
    st.sampled_from(["m1", "m2", "flat-3", "../x", "a/b", "/etc/passwd", "..", "m1.glmap", "~x"]),
    st.text(max_size=16),
)
file_refs = st.one_of(
    st.sampled_from(["/etc/passwd", "/dev/zero", "/nonexistent.png", "relative.png", "/tmp"]),
    st.text(max_size=20),
)


def _mutate(args: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    node = args
    keys = path.split(".")
    for key in keys[:-1]:
        if not isinstance(node.get(key), dict):
            node[key] = {}
        node = node[key]
    if value is None and keys[-1] != "session":
        node.pop(keys[-1], None)
    else:
        node[keys[-1]] = value
    return args


@st.composite
def frame_call(draw: st.DrawFn) -> dict[str, Any]:
    args = copy.deepcopy(VALID_FRAME)
    for _ in range(draw(st.integers(0, 2))):
        path = draw(st.sampled_from(FRAME_PATHS))
        if path.endswith("base64"):
            value = draw(base64_junk)
        elif path.endswith("path"):
            value = draw(file_refs)
        else:
            value = draw(json_value)
        args = _mutate(args, path, value)
    return args


def tool_call() -> st.SearchStrategy[tuple[str, dict[str, Any]]]:
    query = st.text(max_size=30) | json_value
    number = st.floats(allow_nan=True, allow_infinity=True) | json_value
    per_tool = {
        "observe_frame": frame_call(),
        "find_instance": st.fixed_dictionaries({"query": query}, optional={"top_k": number}),
        "find_region": st.fixed_dictionaries({"query": query}, optional={"top_k": number}),
        "what_is_at": st.fixed_dictionaries(
            {"x": number, "y": number}, optional={"radius": number}
        ),
        "describe_unit": st.fixed_dictionaries({"id": st.integers(-5, 20) | json_value}),
        "map_summary": st.fixed_dictionaries({}, optional={"include_image": st.booleans()}),
        "new_map": st.fixed_dictionaries({}, optional={"name": names, "session": names}),
        "save_map": st.fixed_dictionaries(
            {"name": names}, optional={"overwrite": st.booleans() | json_value}
        ),
        "load_map": st.fixed_dictionaries({"name": names}),
        "list_maps": st.just({}),
        "render_view": st.fixed_dictionaries(
            {"target": st.sampled_from(["instance", "region", "map", "pose", "situated"])},
            optional={
                "unit_id": st.integers(-2, 12) | json_value,
                "pose": st.just(VALID_FRAME["pose"]) | json_value,
                "x": number,
                "y": number,
                "heading_deg": number,
                "context": st.booleans() | json_value,
                "width": st.integers(-10, 200),
                "height": st.integers(-10, 200),
            },
        ),
        "export_ply": st.fixed_dictionaries(
            {"name": names},
            optional={
                "unit_id": st.integers(-2, 12) | json_value,
                "overwrite": st.booleans() | json_value,
            },
        ),
        "sim_step": st.fixed_dictionaries(
            {"action": st.sampled_from(["move_forward", "turn_left", "stop", "jump"]) | json_value},
            optional={"repeat": st.integers(-1, 3)},
        ),
        "sim_reset": st.fixed_dictionaries(
            {},
            optional={
                "goal": st.sampled_from(["sofa", "tv", "sofaa"]) | st.text(max_size=10),
                "seed": st.integers(-1, 5),
                "task": st.sampled_from(["objectnav", "instnav", "fly"]),
            },
        ),
        "no_such_tool": st.dictionaries(st.text(max_size=5), json_value, max_size=3),
    }
    junk_args = st.dictionaries(st.text(max_size=8), json_value, max_size=4)
    weighted = [*TOOLS, "observe_frame", "observe_frame", "observe_frame", "save_map"]
    return st.sampled_from(weighted).flatmap(
        lambda name: st.tuples(
            st.just(name),
            st.integers(0, 3).flatmap(lambda k: per_tool[name] if k else junk_args),
        )
    )


class Harness:
    """One in-memory client session kept open across examples through a blocking portal."""

    def __init__(self, portal: anyio.from_thread.BlockingPortal, client: Client, root: Path):
        self.portal, self.client, self.root = portal, client, root
        self.verified: dict[str, tuple[Any, ...]] = {}  # see check_maps_folder

    def call(self, name: str, args: dict[str, Any]) -> Any:
        async def bounded() -> Any:
            with anyio.fail_after(CALL_TIMEOUT):
                return await self.client.call_tool(name, args)

        return self.portal.call(bounded)

    def frames(self) -> int:
        result = self.call("map_summary", {"include_image": False})
        assert not result.is_error, result.content[0].text
        return json.loads(result.content[0].text)["summary"]["frames"]


@pytest.fixture(scope="module")
def harness(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Harness]:
    root = tmp_path_factory.mktemp("props")
    server = build_server(
        config(
            root,
            max_frame_bytes=64 * 1024,
            max_frame_pixels=200_000,
            sim_size=(64, 48),
            render_size=(48, 32),
        )
    )
    with (
        anyio.from_thread.start_blocking_portal() as portal,
        portal.wrap_async_context_manager(Client(server)) as client,
    ):
        yield Harness(portal, client, root)


def check_maps_folder(root: Path, verified: dict[str, tuple[Any, ...]]) -> None:
    """Only `maps/` was written, and it holds complete map and PLY files and nothing else.

    `verified`: file name -> its stamp when it was last read whole; a file unchanged since
    (inode, size, mtime and the first 100 bytes: SQLite's header counts every commit) is
    not read again.
    """
    assert {p.name for p in root.iterdir()} <= {"maps"}
    maps = root / "maps"
    for path in maps.iterdir() if maps.exists() else ():
        assert path.suffix in (".glmap", ".ply") and not path.name.startswith("."), path.name
        stat = path.stat()
        with path.open("rb") as f:
            stamp = (stat.st_ino, stat.st_size, stat.st_mtime_ns, f.read(100))
        if verified.get(path.name) == stamp:
            continue
        if path.suffix == ".ply":
            assert len(read_ply(path)) > 0  # a complete export
        else:
            MapStore.open(path).close()  # a complete, readable store
        verified[path.name] = stamp


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(calls=st.lists(tool_call(), min_size=1, max_size=6))
def test_random_and_malformed_calls_never_crash_hang_or_half_write(harness, calls):
    for name, args in calls:
        before = harness.frames() if name == "observe_frame" else None
        result = harness.call(name, args)
        if result.is_error:
            text = result.content[0].text
            # A crash is worded as a bug to report; a tool error says what to fix.
            assert BUG_NOTE not in text, f"crash in {name}: {args}: {text}"
            assert text.strip() != f"Error executing tool {name}", f"crash in {name}: {args}"
            if before is not None:
                assert harness.frames() == before, f"a rejected frame changed the map: {text}"
    check_maps_folder(harness.root, harness.verified)
    assert not harness.call("list_maps", {}).is_error
