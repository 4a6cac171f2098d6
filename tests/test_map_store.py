"""The SQLite map store: exact round trips, refusal of foreign files, no partial writes."""

import hashlib
import io
import json
import shutil
import sqlite3

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.map.store import SCHEMA_VERSION, InvalidStoreError
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
    assert len(glmap.structure) > 0 and again.structure.equals(glmap.structure)


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
    assert len(copy.structure) > 0 and copy.structure.equals(glmap.structure)
    with pytest.raises(StoreError, match="already exists"):
        glmap.save_as(tmp_path / "b.glmap")
    assert not list(tmp_path.glob(".*.tmp"))


def test_a_missing_folder_is_named_in_the_error(tmp_path):
    with pytest.raises(StoreError, match="does not exist"):
        GLMap.open(tmp_path / "nope" / "m.glmap", embedder=HashingEmbedder())


def _execute(path, *statements):
    conn = sqlite3.connect(path)
    with conn:
        for sql, *params in statements:
            conn.execute(sql, *params)
    conn.close()


def _as_version_1(path):
    """Rewrite a store as schema version 1 wrote it: no structure table or settings."""
    conn = sqlite3.connect(path)
    config = json.loads(conn.execute("SELECT value FROM meta WHERE key = 'config'").fetchone()[0])
    for key in ("structure_voxel", "structure_stride"):
        del config[key]
    conn.close()
    _execute(
        path,
        ("DROP TABLE structure",),
        ("UPDATE meta SET value = '1' WHERE key = 'schema_version'",),
        ("UPDATE meta SET value = ? WHERE key = 'config'", (json.dumps(config),)),
    )


def _meta(path, key):
    conn = sqlite3.connect(path)
    row = conn.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
    conn.close()
    return None if row is None else row[0]


def test_a_version_1_map_opens_and_becomes_version_2_with_its_next_frame(tmp_path):
    path = tmp_path / "old.glmap"
    glmap, boxes = _build(path, frames=1)
    glmap.close()
    _as_version_1(path)
    before = _digest(path)
    old = GLMap.open(path, embedder=HashingEmbedder())
    assert len(old.structure) == 0 and sorted(old.instances) == sorted(glmap.instances)
    assert _digest(path) == before  # opening migrates in memory only
    frame, ids = scenes.view(boxes, (-2.5, -1.5, 1.4), (0.0, 0.0, 0.4))
    old.integrate(frame, scenes.semantics(ids, TEXTS, REGION))
    old.close()
    assert _meta(path, "schema_version") == str(SCHEMA_VERSION) == "2"
    again = GLMap.open(path, embedder=HashingEmbedder())
    assert len(again.structure) > 0 and again.structure.equals(old.structure)


def _fail_inserts_into(path, table):
    _execute(
        path,
        (
            f"CREATE TRIGGER fail BEFORE INSERT ON {table} "
            "BEGIN SELECT RAISE(ABORT, 'simulated disk failure'); END",
        ),
    )


@pytest.mark.parametrize("version", [1, 2])
def test_a_frame_whose_commit_fails_changes_neither_the_file_nor_the_map(tmp_path, version):
    path = tmp_path / "room.glmap"
    glmap, boxes = _build(path, frames=1)
    glmap.close()
    if version == 1:
        _as_version_1(path)
    _fail_inserts_into(path, "structure" if version == 2 else "occupancy")
    before = _digest(path)
    glmap = GLMap.open(path, embedder=HashingEmbedder())
    state = (dict(glmap.instances), dict(glmap.structure.chunks), len(glmap.trajectory))
    frame, ids = scenes.view(boxes, (-2.5, -1.5, 1.4), (0.0, 0.0, 0.4))
    with pytest.raises(StoreError, match="simulated disk failure"):
        glmap.integrate(frame, scenes.semantics(ids, TEXTS, REGION))
    assert (dict(glmap.instances), dict(glmap.structure.chunks), len(glmap.trajectory)) == state
    glmap.close()
    assert _digest(path) == before
    assert _meta(path, "schema_version") == str(version)


def _npy(arr, allow_pickle=False):
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=allow_pickle)
    return buf.getvalue()


def _huge_header():
    buf = io.BytesIO()
    header = {"descr": "<f4", "fortran_order": False, "shape": (10**12, 3)}
    np.lib.format.write_array_header_1_0(buf, header)
    return buf.getvalue() + b"\0" * 24


CRAFTED = {
    "garbage-blob": ("UPDATE instances SET means = ?", (b"\x93NUMPY garbage",)),
    "text-instead-of-blob": ("UPDATE instances SET covs = 'abc'",),
    "object-array-blob": (
        "UPDATE instances SET colors = ?",
        (_npy(np.array([1, "a"], dtype=object), allow_pickle=True),),
    ),
    "huge-array-header": ("UPDATE instances SET means = ?", (_huge_header(),)),
    "short-array": ("UPDATE instances SET opacities = ?", (_npy(np.ones(1, np.float32)),)),
    "nan-means": (
        "UPDATE instances SET means = ?",
        (_npy(np.full((1, 3), np.nan, np.float32)),),
    ),
    "schema-version-abc": ("UPDATE meta SET value = 'abc' WHERE key = 'schema_version'",),
    "config-not-json": ("UPDATE meta SET value = '{voxel' WHERE key = 'config'",),
    "config-missing": ("DELETE FROM meta WHERE key = 'config'",),
    "config-wrong-type": (
        "UPDATE meta SET value = json_set(value, '$.cell_size', 'big') WHERE key = 'config'",
    ),
    "tiny-cell-size": (
        "UPDATE meta SET value = json_set(value, '$.cell_size', 1e-9) WHERE key = 'config'",
    ),
    "next-id-abc": ("UPDATE meta SET value = 'abc' WHERE key = 'next_id'",),
    "next-id-reused": ("UPDATE meta SET value = '2' WHERE key = 'next_id'",),
    "next-id-equal-to-the-largest-id": (
        "UPDATE meta SET value = (SELECT CAST(MAX(id) AS TEXT) FROM "
        "(SELECT id FROM instances UNION SELECT id FROM regions)) WHERE key = 'next_id'",
    ),
    "missing-table": ("DROP TABLE regions",),
    "dangling-region-members": ("UPDATE regions SET instance_ids = '[1, 2, 99]'",),
    "wrong-embedding-size": (
        "UPDATE instances SET embedding = ? WHERE id = 1",
        (_npy(np.ones(7, np.float32)),),
    ),
    "long-instance-embedding": (
        "UPDATE instances SET embedding = ? WHERE id = 1",
        (_npy(np.full(HashingEmbedder().dim, 1e30, np.float32)),),
    ),
    "short-region-embedding": (
        "UPDATE regions SET embedding = ?",
        (_npy(np.full(HashingEmbedder().dim, 1e-3, np.float32)),),
    ),
    "label-is-a-blob": ("UPDATE instances SET label = x'00ff'",),
    "bad-pose": ("UPDATE frames SET pose = ?", (_npy(np.full((4, 4), 2.0)),)),
    "bad-floor": ("UPDATE meta SET value = 'NaN' WHERE key = 'floor_z'",),
    "structure-keys-elsewhere": ("UPDATE structure SET ci = ci + 1000",),
    "version-1-with-a-structure-table": (
        "UPDATE meta SET value = '1' WHERE key = 'schema_version'",
    ),
}


def test_a_stored_zero_embedding_opens(tmp_path, one_frame_store):
    path = tmp_path / "room.glmap"
    shutil.copy(one_frame_store, path)
    dim = HashingEmbedder().dim
    _execute(
        path,
        ("UPDATE instances SET embedding = ? WHERE id = 1", (_npy(np.zeros(dim, np.float32)),)),
    )
    glmap = GLMap.open(path, embedder=HashingEmbedder())
    assert not glmap.instances[1].embedding.any()
    glmap.close()


@pytest.fixture(scope="module")
def one_frame_store(tmp_path_factory):
    path = tmp_path_factory.mktemp("store") / "room.glmap"
    _build(path, frames=1)[0].close()
    return path


@pytest.mark.parametrize("sql", list(CRAFTED.values()), ids=list(CRAFTED))
def test_a_crafted_map_file_is_refused_and_left_unchanged(tmp_path, one_frame_store, sql):
    path = tmp_path / "room.glmap"
    shutil.copy(one_frame_store, path)
    _execute(path, sql)
    before = _digest(path)
    with pytest.raises(InvalidStoreError, match="is not a valid GLMap store: .+"):
        GLMap.open(path, embedder=HashingEmbedder())
    assert _digest(path) == before


def test_open_names_a_config_or_embedder_of_another_kind_and_a_nul_in_the_path(tmp_path):
    path = tmp_path / "m.glmap"
    with pytest.raises(InvalidInputError, match="config is dict, not MapConfig"):
        GLMap.open(path, config={"voxel_size": 0.02}, embedder=HashingEmbedder())  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="embedder is str, not an Embedder"):
        GLMap.open(path, embedder="minilm")  # type: ignore[arg-type]
    with pytest.raises(StoreError, match="holds a NUL character"):
        GLMap.open(tmp_path / "m\x00.glmap", embedder=HashingEmbedder())
    assert list(tmp_path.iterdir()) == []  # nothing was written


@pytest.mark.parametrize("bad", [3, None, 2.5, b"m.glmap"])
def test_a_map_path_that_is_no_file_name_is_refused_naming_its_type(tmp_path, monkeypatch, bad):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(StoreError, match=rf"map path .+ \({type(bad).__name__}\) is no file name"):
        GLMap.open(bad, embedder=HashingEmbedder())
    glmap = GLMap(embedder=HashingEmbedder())
    with pytest.raises(StoreError, match="is no file name; give a str or a Path"):
        glmap.save_as(bad)
    assert glmap.store is None and list(tmp_path.iterdir()) == []
