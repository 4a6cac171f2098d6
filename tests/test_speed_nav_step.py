"""Shortcuts of the agent's step that must not change a bit: frustum culling of the id
pass, cached Gaussian bounds, the structure update's chunk set."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np

from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Pose
from glmap_tools.map.structure import _distinct_chunks
from glmap_tools.sim.layout_io import layout_from_dict
from glmap_tools.sim.render import CameraSpec, SceneRenderer


def _room_with_objects():
    objects = [
        {"id": 10 + k, "category": "box", "mesh": "primitive/box",
         "position": [0.5 + 1.0 * (k % 5), 0.5 + 1.0 * (k // 5), 0], "size": [0.4, 0.4, 0.6]}
        for k in range(25)
    ]  # fmt: skip
    room = {"id": 1, "type": "studio", "polygon": [[0, 0], [5, 0], [5, 5], [0, 5]]}
    return layout_from_dict({"rooms": [room], "objects": objects})


def test_the_id_pass_gives_the_same_images_when_it_skips_objects_out_of_view() -> None:
    renderer = SceneRenderer(_room_with_objects(), CameraSpec(160, 120))
    rng = np.random.default_rng(0)
    skipped = 0
    for _ in range(24):
        eye = np.array([rng.uniform(0.2, 4.8), rng.uniform(0.2, 4.8), rng.uniform(0.2, 2.0)])
        yaw, pitch = rng.uniform(0, 2 * np.pi), rng.uniform(-1.0, 1.0)
        ahead = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
        pose = Pose.looking_at(eye, eye + ahead)
        skipped += int((~renderer._in_view(pose)).sum())
        culled = renderer.render(pose)
        renderer._in_view = lambda pose: np.ones(25, dtype=bool)  # type: ignore[method-assign]
        everything = renderer.render(pose)
        del renderer._in_view
        np.testing.assert_array_equal(culled.rgb, everything.rgb)
        np.testing.assert_array_equal(culled.depth, everything.depth)
        np.testing.assert_array_equal(culled.instance_mask, everything.instance_mask)
    renderer.close()
    assert skipped > 24 * 5  # the test views do leave objects out


def test_cached_bounds_are_the_means_extremes_and_callers_cannot_spoil_them() -> None:
    rng = np.random.default_rng(1)
    n = 50
    g = GaussianSet(
        rng.normal(size=(n, 3)), np.tile(np.eye(3), (n, 1, 1)), np.full((n, 3), 0.5),
        np.full(n, 0.8), np.ones(n),
    )  # fmt: skip
    lo, hi = g.bounds()
    np.testing.assert_array_equal(lo, g.means.min(axis=0))
    np.testing.assert_array_equal(hi, g.means.max(axis=0))
    lo -= 1.0  # a caller widening its copy
    np.testing.assert_array_equal(g.bounds()[0], g.means.min(axis=0))


def test_the_touched_chunks_are_the_distinct_chunk_rows() -> None:
    rng = np.random.default_rng(2)
    for n, low in ((0, 0), (1, -3), (500, -40), (5000, 7)):
        chunks = rng.integers(low, low + 30, (n, 2))
        expected = {(int(i), int(j)) for i, j in chunks.tolist()}
        assert _distinct_chunks(chunks) == expected
