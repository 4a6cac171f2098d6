"""Shared fixtures of the server tests: a small ray-cast scene and a fast server config.

No tests here; the other tests/test_server_*.py files import from it.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
from mcp import Client

from glmap_tools import synthetic
from glmap_tools.app.frames import observe_arguments
from glmap_tools.map import MapConfig
from glmap_tools.server import ServerConfig

OBJECTS = {
    1: ("chair", "a red wooden chair"),
    2: ("table", "a brown dining table"),
    3: ("chair", "a blue office chair"),
}
GROUPS = [{"id": 1, "description": "dining corner with a table and a chair", "members": [1, 2]}]


def scene() -> list[synthetic.Box]:
    return (
        synthetic.floor()
        + synthetic.chair(0.0, 0.0, object_id=1)
        + synthetic.table(1.4, 0.3, 2)
        + synthetic.chair(-1.6, 0.4, color=(0.2, 0.3, 0.8), object_id=3)
    )


@functools.lru_cache(maxsize=8)
def view(eye: tuple[float, float, float], width: int = 160, height: int = 120):  # type: ignore[no-untyped-def]
    return synthetic.view(scene(), eye, (0.0, 0.3, 0.4), width, height)


def frame_args(
    eye: tuple[float, float, float] = (0.0, -2.6, 1.4), groups: bool = True, **kw: Any
) -> dict[str, Any]:
    """observe_frame arguments of the test scene seen from `eye`."""
    frame, ids = view(eye, **kw)
    visible = sorted(int(i) for i in np.unique(ids) if i)
    objects = [{"id": i, "label": OBJECTS[i][0], "description": OBJECTS[i][1]} for i in visible]
    return observe_arguments(frame, ids, objects, GROUPS if groups else [])


def config(tmp_path: Path, **kw: Any) -> ServerConfig:
    """A fast test server: hashing embedder, 4 cm voxels (small frames), no warm-up."""
    return ServerConfig(
        maps_dir=tmp_path / "maps",
        embedder="hashing",
        map_config=MapConfig(voxel_size=0.04),
        warm_up=False,
        **kw,
    )


async def counts(client: Client) -> tuple[int, int, int]:
    """(frames, instances, regions) of the session's map."""
    result = await client.call_tool("map_summary", {"include_image": False})
    summary = json.loads(result.content[0].text)["summary"]
    return summary["frames"], summary["instances"], summary["regions"]
