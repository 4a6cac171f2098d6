"""The top-down image's frame: scales from a ladder, a frame kept while the map fits, metre
ticks, labels that never overlap, and memory bounded by the pixel cap, not the map's extent."""

from __future__ import annotations

import itertools
import re
import tracemalloc

import numpy as np
import pytest
from mcp import Client

from glmap_tools.errors import InvalidInputError
from glmap_tools.map.occupancy import CHUNK
from glmap_tools.server import build_server
from glmap_tools.views import draw_topdown
from glmap_tools.views.topdown_frame import SCALES, choose_frame
from tests.test_server_fixtures import config, frame_args
from tests.test_views_fixtures import build_wall_scene, empty_map

SCALE_AND_CORNER = re.compile(r"([\d.]+) cm per pixel; the top-left corner is world \(x, y\) = "
                              r"\((-?[\d.]+), (-?[\d.]+)\)")  # fmt: skip


@pytest.fixture(scope="module")
def scene():
    return build_wall_scene()


def disjoint(boxes) -> bool:
    return all(
        a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
        for a, b in itertools.combinations(boxes, 2)
    )


def test_scales_come_from_the_ladder_and_corners_snap_so_a_growing_map_keeps_its_frame():
    rng = np.random.default_rng(0)
    for _ in range(200):
        lo = rng.uniform(-50, 50, 2)
        hi = lo + rng.uniform(0.1, 60, 2)
        frame = choose_frame(lo, hi, 0.005, 768)
        assert frame.metres_per_pixel in SCALES and frame.holds(lo, hi)
        assert max(frame.width, frame.height) <= 768
        # Growing a little inside the snapped corners changes nothing.
        inner_hi = np.minimum(hi + 0.001, [frame.x1, frame.y1])
        assert choose_frame(lo, inner_hi, 0.005, 768) == frame


def test_a_frame_passed_back_is_kept_while_the_map_fits_and_ticks_mark_whole_metres(scene):
    first = draw_topdown(scene.glmap, max_side=400)
    wider = choose_frame(
        np.array([first.frame.x0 - 3, first.frame.y0 - 3]),
        np.array([first.frame.x1 + 3, first.frame.y1 + 3]),
        0.005,
        400,
    )
    kept = draw_topdown(scene.glmap, max_side=400, frame=wider)
    assert kept.frame == wider and kept.frame != first.frame
    assert draw_topdown(scene.glmap, max_side=400, frame=first.frame).frame == first.frame
    assert first.tick > 0 and f"ticks every {first.tick:g} m" in first.describe()
    col, _ = first.world_to_pixel(0.0, 0.0)  # a tick at x = 0 on the bottom edge
    assert (first.rgb[-3, int(round(col))] == 0).all()


def test_labels_never_overlap_even_when_crowded(scene):
    roomy = draw_topdown(scene.glmap)
    crowded = draw_topdown(scene.glmap, max_side=64)
    assert disjoint(roomy.label_boxes) and disjoint(crowded.label_boxes)
    assert len(crowded.label_boxes) < len(roomy.label_boxes)
    assert any("left out" in line for line in crowded.legend)


def test_a_fixed_scale_is_kept_or_refused_when_it_cannot_fit(scene):
    image = draw_topdown(scene.glmap, metres_per_pixel=0.05)
    assert image.metres_per_pixel == 0.05 and "5 cm per pixel" in image.describe()
    with pytest.raises(InvalidInputError, match="coarser metres_per_pixel"):
        draw_topdown(scene.glmap, metres_per_pixel=0.0001)
    with pytest.raises(InvalidInputError, match="positive"):
        draw_topdown(scene.glmap, metres_per_pixel=-1.0)


def test_memory_follows_the_pixel_cap_not_two_observed_spots_150_m_apart():
    glmap = empty_map()
    far = int(150 / glmap.config.cell_size) // CHUNK  # chunks apart along x and y
    seen = np.zeros((2, CHUNK, CHUNK), np.int32)
    seen[0, 10:20, 10:20] = 3
    glmap.occupancy.chunks[(0, 0)] = seen
    glmap.occupancy.chunks[(far, far)] = seen.copy()
    tracemalloc.start()
    try:
        image = draw_topdown(glmap, max_side=512)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert max(image.rgb.shape[:2]) <= 512
    assert peak < 16 * 2**20, f"{peak / 2**20:.0f} MiB"  # a dense grid would be ~300 MiB


@pytest.mark.anyio
async def test_map_summary_keeps_its_scale_and_corner_from_call_to_call(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        texts = []
        for eye in [(0.0, -2.6, 1.4), (0.0, -2.6, 1.4), (0.1, -2.5, 1.4)]:
            await client.call_tool("observe_frame", frame_args(eye))
            result = await client.call_tool("map_summary", {})
            texts.append(result.content[1].text)
    frames = [SCALE_AND_CORNER.search(t).groups() for t in texts]
    assert float(frames[0][0]) / 100 in SCALES
    assert frames[0] == frames[1] == frames[2]


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"
