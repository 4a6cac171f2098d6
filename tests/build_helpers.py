"""Small tours on disk and a map comparison, for the build tests."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

BENCH = Path(__file__).resolve().parents[1] / "glmap_tools" / "data" / "benchmark" / "bench"


def write_small_tour(scene: str, folder: Path, frames: int = 8) -> Path:
    """`frames` frames (160x120, annotated) of a tour of bench scene `scene` into `folder`."""
    from glmap_tools.sim.layout_io import load_layout
    from glmap_tools.sim.render import CameraSpec
    from glmap_tools.worlds.tour import write_tour

    layout = load_layout(BENCH / scene / "layout.json")
    write_tour(layout, folder, CameraSpec(160, 120), step=0.5, spin=4, max_frames=frames)
    return folder


def assert_same_map(a, b) -> None:  # two GLMap
    """The same units (ids, labels, texts, observations, Gaussians), occupancy and poses."""
    assert sorted(a.instances) == sorted(b.instances)
    for uid, u in a.instances.items():
        v = b.instances[uid]
        seen_u = (u.label, u.text, u.observations, u.first_frame, u.last_frame)
        assert seen_u == (v.label, v.text, v.observations, v.first_frame, v.last_frame), uid
        np.testing.assert_allclose(u.embedding, v.embedding, atol=1e-6)
        assert len(u.gaussians) == len(v.gaussians), uid
        np.testing.assert_allclose(u.gaussians.means, v.gaussians.means, atol=1e-9)
        np.testing.assert_allclose(u.gaussians.covs, v.gaussians.covs, atol=1e-12)
        np.testing.assert_allclose(u.gaussians.colors, v.gaussians.colors, atol=1e-6)
    assert sorted(a.regions) == sorted(b.regions)
    for rid, r in a.regions.items():
        s = b.regions[rid]
        assert (sorted(r.instance_ids), r.text) == (sorted(s.instance_ids), s.text), rid
    assert a.next_id == b.next_id and a.floor_z == b.floor_z
    assert sorted(a.occupancy.chunks) == sorted(b.occupancy.chunks)
    for key, chunk in a.occupancy.chunks.items():
        np.testing.assert_array_equal(chunk, b.occupancy.chunks[key])
    assert sorted(a.structure.chunks) == sorted(b.structure.chunks)
    np.testing.assert_allclose(
        a.structure.gaussians().means, b.structure.gaussians().means, atol=1e-9
    )
    np.testing.assert_allclose(np.array(a.trajectory), np.array(b.trajectory))
