"""The bundled real Redwood frames, end to end: ingest, fuse, store, CLI."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from glmap_tools.cli import main as glmap_main
from glmap_tools.ingest.cli import bundled_folder
from glmap_tools.ingest.datasets import open_sequence
from glmap_tools.language.minilm import default_embedder
from glmap_tools.map import GLMap, MapConfig


@pytest.fixture(scope="module")
def redwood_map():
    glmap = GLMap(MapConfig(), embedder=default_embedder())
    per_frame = {}
    for item in open_sequence(bundled_folder()).frames():
        report = glmap.integrate(item.frame, item.semantics, item.index)
        for obj in item.semantics.objects:
            gid = report.local_to_global[obj.local_id]
            per_frame.setdefault(obj.label, []).append((gid, obj))
    return glmap, per_frame


def test_every_annotated_object_becomes_one_instance_seen_in_all_five_frames(redwood_map):
    glmap, per_frame = redwood_map
    assert len(glmap.instances) == len(per_frame) == 5
    for label, seen in per_frame.items():
        assert len({gid for gid, _ in seen}) == 1, label
        assert glmap.instances[seen[0][0]].observations == 5, label


def test_both_annotated_regions_are_kept_with_their_members(redwood_map):
    glmap, per_frame = redwood_map
    ids = {label: seen[0][0] for label, seen in per_frame.items()}
    members = sorted(tuple(r.instance_ids) for r in glmap.regions.values())
    assert members == sorted(
        [
            tuple(sorted((ids["lounge chair"], ids["curtain"]))),
            tuple(sorted((ids["curtain"], ids["door frame"]))),
        ]
    )


def test_gaussians_of_the_same_object_agree_across_frames_within_5_cm(redwood_map):
    glmap, _ = redwood_map
    seq = open_sequence(bundled_folder())
    items = list(seq.frames())
    for label in ("lounge chair", "curtain", "door frame"):
        fits = []
        for item in items:
            obj = next(o for o in item.semantics.objects if o.label == label)
            from glmap_tools.geometry import backproject

            cloud = backproject(
                item.frame.depth,
                item.frame.intrinsics,
                item.frame.pose,
                item.frame.rgb,
                obj.mask,
                glmap.config.max_range,
            )
            fits.append(glmap.estimator.fit(cloud.points, cloud.colors))
        centroids = np.array([f.means.mean(0) for f in fits])
        assert np.linalg.norm(centroids - centroids.mean(0), axis=1).max() < 0.05, label
        # Every frame's Gaussians lie on the fused instance: nearest fused mean within 5 cm.
        fused = next(u for u in glmap.instances.values() if u.label == label).gaussians
        tree = cKDTree(fused.means)
        for f in fits:
            d, _ = tree.query(f.means)
            assert np.median(d) < 0.05 and np.percentile(d, 95) < 0.05, label


def test_the_floor_estimate_matches_the_annotated_floor_and_the_room_has_free_space(redwood_map):
    glmap, per_frame = redwood_map
    floor = glmap.instances[per_frame["floor"][0][0]]
    assert glmap.floor_z is not None and abs(glmap.floor_z - floor.centroid[2]) < 0.02
    assert glmap.trajectory[0][2, 3] > glmap.floor_z + 0.3  # the camera is above it
    dense = glmap.occupancy.to_dense()
    assert (dense.state == 1).sum() > 100 and (dense.state == 2).sum() > 100


def test_glmap_build_writes_a_map_and_prints_a_summary(tmp_path, capsys):
    out = tmp_path / "redwood.glmap"
    assert glmap_main(["build", "--out", str(out), "--quiet", "--embedder", "hashing"]) == 0
    text = capsys.readouterr().out
    assert "instances" in text and "lounge chair" in text
    reopened = GLMap.open(
        out,
        embedder=__import__(
            "glmap_tools.language.embed", fromlist=["HashingEmbedder"]
        ).HashingEmbedder(),
    )
    assert len(reopened.instances) >= 5
    assert not list(tmp_path.glob(".*building*"))


def test_glmap_build_refuses_to_overwrite_without_the_flag(tmp_path, capsys):
    out = tmp_path / "m.glmap"
    out.write_bytes(b"keep me")
    assert glmap_main(["build", "--out", str(out), "--quiet", "--embedder", "hashing"]) == 1
    assert "--overwrite" in capsys.readouterr().err
    assert out.read_bytes() == b"keep me"
