"""Fuzzing the map loader: a mutated store either opens as a working map or is refused.

Every example copies a valid two-frame store, mutates a few of its rows, blobs, meta values
or tables (hypothesis), and opens it. The only acceptable outcomes are a map whose queries
and renders work, or a `StoreError` naming the problem; any other exception fails.
"""

from __future__ import annotations

import contextlib
import io
import shutil
import sqlite3

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from glmap_tools import synthetic as scenes
from glmap_tools.errors import StoreError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.map.store_check import COLUMNS
from glmap_tools.views import render_map, view_intrinsics

TEXTS = {1: ("table", "a brown wooden dining table"), 2: ("chair", "a red chair")}
REGION = [(1, "dining area with a table and a chair", (1, 2))]
TABLES = tuple(COLUMNS)
BOXES = scenes.floor(3.0) + scenes.table(0.0, 0.0, 1) + scenes.chair(0.0, -0.8, object_id=2)
FRAME = scenes.view(BOXES, (0.0, -2.5, 1.4), (0.0, 0.0, 0.4), 128, 96)


@pytest.fixture(scope="module")
def valid_store(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "room.glmap"
    glmap = GLMap.open(path, MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    for eye in [(0.3, -3.0, 1.4), (-2.5, -1.5, 1.4)]:
        frame, ids = scenes.view(BOXES, eye, (0.0, 0.0, 0.4))
        glmap.integrate(frame, scenes.semantics(ids, TEXTS, REGION))
    glmap.close()
    return path


def _reheader(data: bytes, descr: str, shape: tuple[int, ...]) -> bytes:
    """Another .npy header in front of the same data bytes."""
    buf = io.BytesIO()
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    np.lib.format.write_array_header_1_0(buf, header)
    start = data.find(b"\n") + 1 if data.startswith(b"\x93NUMPY") else 0
    return buf.getvalue() + data[start:]


values = st.one_of(
    st.none(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=20),
    st.sampled_from(["abc", "1", "0", "-1", "[]", "[1, 99]", "null", "{}", "1e309", "NaN"]),
    st.binary(max_size=40),
)
shapes = st.lists(st.sampled_from([0, 1, 2, 3, 4, 64, 2**40]), max_size=3).map(tuple)
descrs = st.sampled_from(["<f4", "<f8", "<u4", "<i4", "<i8", ">f4", "|O", "|b1"])


@st.composite
def mutations(draw):
    """One mutation: (kind, table, column, row pick, payload)."""
    kind = draw(st.sampled_from(["set", "flip", "truncate", "reheader", "delete", "drop"]))
    table = draw(st.sampled_from(TABLES))
    column = draw(st.sampled_from(COLUMNS[table]))
    row = draw(st.integers(min_value=0, max_value=50))
    if kind == "set":
        payload = draw(values)
    elif kind == "flip":
        payload = (draw(st.integers(min_value=0, max_value=400)), draw(st.integers(1, 255)))
    elif kind == "truncate":
        payload = draw(st.integers(min_value=0, max_value=400))
    elif kind == "reheader":
        payload = (draw(descrs), draw(shapes))
    else:
        payload = None
    return kind, table, column, row, payload


def _apply(conn: sqlite3.Connection, mutation) -> None:
    kind, table, column, row, payload = mutation
    exists = conn.execute("SELECT 1 FROM sqlite_master WHERE name = ?", (table,)).fetchone()
    if not exists:
        return
    if kind == "drop":
        conn.execute(f"DROP TABLE {table}")
        return
    rowids = [r[0] for r in conn.execute(f"SELECT rowid FROM {table} ORDER BY rowid")]
    if not rowids:
        return
    rowid = rowids[row % len(rowids)]
    if kind == "delete":
        conn.execute(f"DELETE FROM {table} WHERE rowid = ?", (rowid,))
        return
    (old,) = conn.execute(f"SELECT {column} FROM {table} WHERE rowid = ?", (rowid,)).fetchone()
    raw = old if isinstance(old, bytes) else str(old).encode()
    if kind == "set":
        new = payload
    elif kind == "flip":
        at, bits = payload
        new = bytearray(raw)
        if new:
            new[at % len(new)] ^= bits
        new = bytes(new) if isinstance(old, bytes) else new.decode("utf-8", "replace")
    elif kind == "truncate":
        new = raw[: payload % (len(raw) + 1)]
        new = new if isinstance(old, bytes) else new.decode("utf-8", "replace")
    else:
        new = _reheader(raw, *payload)
    # NOT NULL or a duplicate key: SQLite itself refuses, and the row stays as it was.
    with contextlib.suppress(sqlite3.IntegrityError, OverflowError):
        conn.execute(f"UPDATE {table} SET {column} = ? WHERE rowid = ?", (new, rowid))


def _use(glmap: GLMap) -> None:
    """Everything a client does with an opened map."""
    glmap.summary()
    for uid in [*glmap.instances, *glmap.regions]:
        glmap.unit_details(uid)
    glmap.find_instances("a chair", k=3)
    glmap.find_regions("dining", k=3)
    glmap.units_at(0.0, 0.0, 1.0)
    if glmap.instances or len(glmap.structure):
        pose = scenes.view([], (0.3, -3.0, 1.4), (0.0, 0.0, 0.4), 16, 12)[0].pose
        render_map(glmap, pose, view_intrinsics(16, 12))
    frame, ids = FRAME
    glmap.integrate(frame, scenes.semantics(ids, TEXTS, REGION))


@settings(
    max_examples=100,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(batch=st.lists(mutations(), min_size=1, max_size=3))
def test_a_mutated_store_opens_as_a_working_map_or_is_refused_cleanly(tmp_path, valid_store, batch):
    path = tmp_path / "mutated.glmap"
    shutil.copy(valid_store, path)
    conn = sqlite3.connect(path)
    with conn:
        for mutation in batch:
            _apply(conn, mutation)
    conn.close()
    try:
        glmap = GLMap.open(path, embedder=HashingEmbedder())
    except StoreError as exc:
        assert path.name in str(exc)  # a message about this file, not a bare exception
        return
    try:
        _use(glmap)
    finally:
        glmap.close()


def test_the_unmutated_store_opens_and_works(valid_store):
    glmap = GLMap.open(valid_store, embedder=HashingEmbedder())
    assert len(glmap.instances) == 2 and len(glmap.regions) == 1 and len(glmap.structure)
    _use(glmap)
    glmap.close()


@pytest.mark.parametrize(
    ("shift", "said"),
    [
        ((0.0, -196_600.0, 0.0), "past the map's world_limit"),  # a flipped exponent bit
        ((0.0, -400.0, 0.0), "more than the map's max_span"),
    ],
)
def test_a_stored_pose_no_frame_could_have_had_is_refused_at_open(
    valid_store, tmp_path, shift, said
):
    # Every integrated frame passed the map's bounds; a stored camera beyond them is damage,
    # and a map opened with it would refuse every later frame.
    from glmap_tools.map.store_rows import to_npy

    path = tmp_path / "moved.glmap"
    shutil.copy(valid_store, path)
    conn = sqlite3.connect(path)
    with conn:
        ((blob,),) = conn.execute("SELECT pose FROM frames ORDER BY seq LIMIT 1").fetchall()
        pose = np.load(io.BytesIO(blob))
        pose[:3, 3] += shift
        conn.execute("UPDATE frames SET pose = ? WHERE seq = 1", (to_npy(pose),))
    conn.close()
    with pytest.raises(StoreError, match=said) as refused:
        GLMap.open(path, embedder=HashingEmbedder())
    assert path.name in str(refused.value) and "frame" in str(refused.value)
