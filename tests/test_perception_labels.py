"""Labels files point at geometric segments; the Redwood frames build without annotations."""

from __future__ import annotations

import json
import shutil

import pytest

from glmap_tools.cli import main as glmap_main
from glmap_tools.errors import InvalidInputError
from glmap_tools.ingest.cli import BUNDLED, bundled_folder
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap
from glmap_tools.perception.labels_file import (
    FrameLabels,
    PointedObject,
    labels_from_annotations,
    load_labels_file,
    pointed_labels,
)

LABELS = bundled_folder().with_name(f"{BUNDLED}.labels.json")


def test_the_bundled_labels_file_is_what_its_generator_makes_from_the_annotations():
    shipped = json.loads(LABELS.read_text())
    assert shipped == labels_from_annotations(bundled_folder())
    labels = load_labels_file(LABELS)
    assert sorted(labels) == ["00000", "00001", "00002", "00003", "00004"]
    assert {o.label for o in labels["00000"].objects} == {"lounge chair", "curtain", "door frame"}


def test_the_redwood_frames_without_annotations_build_a_map_with_named_instances(tmp_path):
    folder = tmp_path / "redwood"
    shutil.copytree(bundled_folder(), folder, ignore=shutil.ignore_patterns("annotations"))
    out = tmp_path / "rw.glmap"
    args = ["build", str(folder), "--out", str(out), "--quiet", "--embedder", "hashing"]
    assert glmap_main([*args, "--perception", "geometric", "--labels", str(LABELS)]) == 0
    glmap = GLMap.open(out, embedder=HashingEmbedder())
    try:
        assert sorted(u.label for u in glmap.instances.values()) == [
            "curtain",
            "door frame",
            "lounge chair",
        ]
        assert all(u.observations == 5 for u in glmap.instances.values())
        assert len(glmap.regions) == 2
        chair = next(u for u in glmap.instances.values() if u.label == "lounge chair")
        size = chair.gaussians.bounds()[1] - chair.gaussians.bounds()[0]
        assert 0.4 < size.max() < 1.6  # a chair, not the room
    finally:
        glmap.close()


def test_geometric_perception_on_a_users_folder_needs_a_labels_file(tmp_path, capsys):
    folder = tmp_path / "redwood"
    shutil.copytree(bundled_folder(), folder, ignore=shutil.ignore_patterns("annotations"))
    code = glmap_main(
        ["build", str(folder), "--out", str(tmp_path / "x.glmap"), "--perception", "geometric"]
    )
    assert code != 0
    assert "--labels FILE" in capsys.readouterr().err
    assert not (tmp_path / "x.glmap").exists()


@pytest.mark.parametrize(
    ("frames", "words"),
    [
        ({"a": {"objects": [{"id": 1, "label": "chair"}]}}, "needs 'at'"),
        ({"a": {"objects": [{"id": 1, "at": [[3, -1]], "label": "chair"}]}}, "x, y >= 0"),
        ({"a": {"objects": [{"id": 1, "at": [[3, 4]], "label": " "}]}}, "empty label"),
        ({"a": {"groups": [{"members": [1]}]}}, "needs a 'description'"),
    ],
)
def test_a_malformed_labels_file_names_the_bad_entry(tmp_path, frames, words):
    path = tmp_path / "labels.json"
    path.write_text(json.dumps({"frames": frames}))
    with pytest.raises(InvalidInputError, match=words):
        load_labels_file(path)


def test_points_name_the_segments_under_them_and_a_point_on_nothing_is_reported(tmp_path):
    import numpy as np

    from glmap_tools.perception.geometric import Segment

    def seg(i: int, cols: slice) -> Segment:
        mask = np.zeros((20, 30), bool)
        mask[5:15, cols] = True
        z = np.zeros(3)
        return Segment(
            i, mask, z, z, z, int(mask.sum()), (5, 0, 15, 30), np.zeros((1, 1, 3), np.uint8)
        )

    segments = [seg(1, slice(0, 10)), seg(2, slice(10, 20)), seg(3, slice(20, 30))]
    named = FrameLabels(
        (
            PointedObject(7, ((2, 8), (12, 8)), "sofa", "seat and back"),
            PointedObject(8, ((25, 19),), "lamp", ""),  # 4 px below segment 3: still it
            PointedObject(9, ((5, 0),), "ghost", ""),  # far from any segment
        ),
        ((1, "living room", (7, 8, 9)),),
    )
    labels, groups, missing = pointed_labels(segments, named)
    assert [(lab.segments, lab.label) for lab in labels] == [((1, 2), "sofa"), ((3,), "lamp")]
    assert groups[0].members == (1, 3)
    assert missing == [9]


def test_a_labels_file_that_is_not_utf8_json_is_refused_naming_it(tmp_path):
    path = tmp_path / "labels.json"
    path.write_bytes(b'{"frames": {"a": "\xff"}}')
    with pytest.raises(InvalidInputError, match="labels.json' cannot be read as JSON"):
        load_labels_file(path)


@pytest.mark.parametrize("key", ["objects", "groups"])
def test_a_frame_whose_objects_or_groups_are_not_a_list_is_refused_naming_it(tmp_path, key):
    path = tmp_path / "labels.json"
    path.write_text(json.dumps({"frames": {"00000": {key: 3}}}))
    with pytest.raises(InvalidInputError, match=rf"frames\['00000'\].{key} must be a list, got 3"):
        load_labels_file(path)
