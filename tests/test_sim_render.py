"""Rendering: exact id masks (also above 255), metric depth, non-convex rooms."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import math

import numpy as np

from glmap_tools.geometry import Pose, backproject
from glmap_tools.sim.architecture import triangulate
from glmap_tools.sim.layout import polygon_signed_area
from glmap_tools.sim.layout_io import layout_from_dict
from glmap_tools.sim.render import CameraSpec, SceneRenderer, id_color, ids_from_color

L_SHAPE = [[0, 0], [6, 0], [6, 3], [3, 3], [3, 6], [0, 6]]


def _scene():
    objects = [
        {"id": 300, "category": "sofa", "mesh": "kenney/loungeSofa", "position": [2.0, 0.6, 0],
         "heading": math.pi / 2},
        {"id": 1000, "category": "table", "mesh": "primitive/table", "position": [4.5, 1.5, 0]},
        {"id": 7, "category": "box", "mesh": "primitive/box", "position": [1.5, 4.5, 0],
         "size": [0.5, 0.5, 0.5]},
    ]  # fmt: skip
    return layout_from_dict(
        {"rooms": [{"id": 1, "type": "studio", "polygon": L_SHAPE}], "objects": objects}
    )


def test_id_colours_round_trip_for_every_uint16_id() -> None:
    ids = np.array([1, 7, 255, 256, 300, 1000, 65535])
    seg = np.array([[id_color(int(i)) for i in ids]], dtype=np.uint8)
    np.testing.assert_array_equal(ids_from_color(seg)[0], ids)


def test_ear_clipping_covers_a_non_convex_room_exactly() -> None:
    poly = np.array(L_SHAPE, dtype=float)
    tris = triangulate(poly)
    assert len(tris) == len(poly) - 2
    area = sum(abs(polygon_signed_area(poly[t])) for t in tris)
    assert math.isclose(area, 27.0)


def test_the_mask_holds_only_layout_ids_and_depth_is_metric_at_full_size() -> None:
    layout = _scene()
    renderer = SceneRenderer(layout, CameraSpec(640, 480))
    pose = Pose.looking_at(np.array([1.5, 2.0, 0.88]), np.array([4.5, 1.0, 0.5]))
    view = renderer.render(pose)
    assert set(np.unique(view.instance_mask)) == {0, 300, 1000}
    table = layout.object(1000)
    pts = backproject(view.depth, renderer.intrinsics, pose, mask=view.instance_mask == 1000)
    assert table.distance_to(pts.points[:, :2]).max() < 5e-3
    assert abs(pts.points[:, 2].max() - table.top) < 5e-3  # the table top, seen from above
    assert view.depth.dtype == np.float32 and (view.depth > 0).all()  # walls close the room
    assert view.rgb.dtype == np.uint8 and view.rgb.std() > 10


def test_rendering_the_same_pose_twice_gives_identical_images() -> None:
    renderer = SceneRenderer(_scene(), CameraSpec(160, 120))
    pose = Pose.from_position_heading(1.0, 2.0, 0.88, 0.3)
    a, b = renderer.render(pose), renderer.render(pose)
    np.testing.assert_array_equal(a.rgb, b.rgb)
    np.testing.assert_array_equal(a.depth, b.depth)
    np.testing.assert_array_equal(a.instance_mask, b.instance_mask)


def test_the_colour_pass_reads_the_image_pyrender_reads() -> None:
    """The colour pass skips pyrender's depth read-back; its image is pyrender's own."""
    import pyrender

    from glmap_tools.sim import render as sim_render

    renderer = SceneRenderer(_scene(), CameraSpec(160, 120))
    pose = Pose.looking_at(np.array([1.5, 2.0, 0.88]), np.array([4.5, 1.0, 0.5]))
    passes = renderer._renderer._renderer  # type: ignore[union-attr]
    assert isinstance(passes, sim_render._ColourPassRenderer)
    fast = renderer.render(pose)
    passes.__class__ = pyrender.Renderer  # pyrender's own read-back of colour and depth
    try:
        plain = renderer.render(pose)
    finally:
        passes.__class__ = sim_render._ColourPassRenderer
    assert fast.rgb.std() > 10
    np.testing.assert_array_equal(fast.rgb, plain.rgb)
    np.testing.assert_array_equal(fast.depth, plain.depth)
    np.testing.assert_array_equal(fast.instance_mask, plain.instance_mask)


def test_surfaces_that_tie_in_depth_go_to_the_object_listed_first() -> None:
    # Two boxes in the same place tie in depth on every pixel. pyrender drew its mesh nodes in
    # the order of a set (memory addresses), so which id won differed between renderers.
    boxes = [
        {"id": i, "category": "box", "mesh": "primitive/box", "position": [1.5, 4.5, 0],
         "size": [0.5, 0.5, 0.5]}
        for i in (40, 9, 23)
    ]  # fmt: skip
    layout = layout_from_dict(
        {"rooms": [{"id": 1, "type": "studio", "polygon": L_SHAPE}], "objects": boxes}
    )
    pose = Pose.looking_at(np.array([1.5, 2.5, 0.88]), np.array([1.5, 4.5, 0.25]))
    for _ in range(8):  # new nodes at new addresses each time
        renderer = SceneRenderer(layout, CameraSpec(160, 120))
        ids = set(np.unique(renderer.render(pose).instance_mask)) - {0}
        assert ids == {40}
