"""The SQLite map store: exact round trips, refusal of foreign files, no partial writes."""

import hashlib
import sqlite3

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.perception import FrameSemantics, ObjectObservation

TEXTS = {
    1: ("table", "a brown wooden dining table"),
    2: ("chair", "a wooden chair with a red cushion"),
}
REGION = [(1, "dining area with a table and a chair", (1, 2))]


def _build(path, frames=2):
    glmap = GLMap.open(path, MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    boxes = scenes.floor() + scenes.table(0.0, 0.0, 1) + scenes.chair(0.0, -0.8, object_id=2)
    for eye in [(0.3, -3.0, 1.4), (-2.5, -1.5, 1.4)][:frames]:
        frame, ids = scenes.view(boxes, eye, (0.0, 0.0, 0.4))
        glmap.integrate(frame, scenes.semantics(ids, TEXTS, REGION))
    return glmap, boxes


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_reopening_a_map_reproduces_it_exactly(tmp_path):
    path = tmp_path / "room.glmap"
    glmap, _ = _build(path)
    glmap.close()
    again = GLMap.open(path, embedder=HashingEmbedder())
    assert sorted(again.instances) == sorted(glmap.instances)
    for uid, unit in glmap.instances.items():
        other = again.instances[uid]
        assert other.gaussians.equals(unit.gaussians)
        assert other.text == unit.text and other.label == unit.label
        assert np.array_equal(other.embedding, unit.embedding)
        assert (other.observations, other.first_frame, other.last_frame) == (
            unit.observations,
            unit.first_frame,
            unit.last_frame,
        )
    assert sorted(again.regions) == sorted(glmap.regions)
    for rid, region in glmap.regions.items():
        other = again.regions[rid]
        assert (other.text, other.instance_ids, other.observations) == (
            region.text,
            region.instance_ids,
            region.observations,
        )
        assert np.array_equal(other.embedding, region.embedding)
    assert again.grid.snapshot() == glmap.grid.snapshot()
    assert again.occupancy.equals(glmap.occupancy)
    assert again.next_id == glmap.next_id and again.floor_z == glmap.floor_z
    assert all(
        np.array_equal(a, b) for a, b in zip(again.trajectory, glmap.trajectory, strict=True)
    )
    assert again.config == glmap.config


def test_each_integrate_is_committed_before_it_returns(tmp_path):
    path = tmp_path / "room.glmap"
    glmap, _ = _build(path, frames=1)
    # A second connection sees the frame without any close or flush.
    rows = sqlite3.connect(path).execute("SELECT COUNT(*) FROM instances").fetchone()[0]
    assert rows == len(glmap.instances) == 2


def test_a_refused_frame_leaves_the_file_on_disk_unchanged(tmp_path):
    path = tmp_path / "room.glmap"
    glmap, boxes = _build(path, frames=1)
    before = _digest(path)
    frame, ids = scenes.view(boxes, (0.0, -3.0, 1.4), (0.0, 0.0, 0.4))
    with pytest.raises(InvalidInputError):
        glmap.integrate(frame, FrameSemantics([ObjectObservation(1, "table", "", ids == 42)]))
    assert _digest(path) == before


def test_a_file_that_is_not_sqlite_is_refused_with_a_clear_error(tmp_path):
    path = tmp_path / "notes.glmap"
    path.write_text("hello, I am not a map")
    with pytest.raises(StoreError, match="not a GLMap store"):
        GLMap.open(path, embedder=HashingEmbedder())
    assert path.read_text() == "hello, I am not a map"


def test_an_sqlite_file_of_another_application_is_refused(tmp_path):
    path = tmp_path / "other.db"
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE meta (key TEXT, value TEXT)")
    conn.commit()
    conn.close()
    with pytest.raises(StoreError, match="not a GLMap store"):
        GLMap.open(path, embedder=HashingEmbedder())


def test_a_map_from_a_newer_schema_is_refused(tmp_path):
    path = tmp_path / "room.glmap"
    _build(path, frames=1)[0].close()
    conn = sqlite3.connect(path)
    conn.execute("UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    conn.commit()
    conn.close()
    with pytest.raises(StoreError, match="schema version 99"):
        GLMap.open(path, embedder=HashingEmbedder())


def test_a_map_built_with_another_embedder_is_refused(tmp_path):
    path = tmp_path / "room.glmap"
    _build(path, frames=1)[0].close()

    other = HashingEmbedder(dim=256)
    with pytest.raises(StoreError, match="same embedder"):
        GLMap.open(path, embedder=other)


def test_save_as_writes_a_copy_and_refuses_to_overwrite(tmp_path):
    glmap, _ = _build(tmp_path / "a.glmap", frames=1)
    glmap.save_as(tmp_path / "b.glmap")
    copy = GLMap.open(tmp_path / "b.glmap", embedder=HashingEmbedder())
    assert copy.grid.snapshot() == glmap.grid.snapshot()
    with pytest.raises(StoreError, match="already exists"):
        glmap.save_as(tmp_path / "b.glmap")
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_missing_folder_is_named_in_the_error(tmp_path):
    with pytest.raises(StoreError, match="does not exist"):
        GLMap.open(tmp_path / "nope" / "m.glmap", embedder=HashingEmbedder())
