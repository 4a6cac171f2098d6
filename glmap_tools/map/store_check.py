"""Reading a map file defensively: every table, row, blob and reference is checked.

A map file may come from anywhere (a shared folder, an upload), so `read_state` trusts
nothing: array blobs are parsed header first (dtype, shape and byte length checked before
any data is read; no pickle), values must be finite and in range, the config must pass its
schema (pydantic) and sane bounds, and every id a row refers to must exist. Anything else is
refused with an `InvalidStoreError` that names the table, the row and what is wrong.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import sqlite3
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import TypeAdapter, ValidationError

from glmap_tools.errors import GLMapError, StoreError
from glmap_tools.gaussians.estimator import EstimatorConfig
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Pose
from glmap_tools.map.config import MapConfig
from glmap_tools.map.occupancy import CHUNK as OCC_CHUNK
from glmap_tools.map.occupancy import OccupancyGrid
from glmap_tools.map.structure import StructureChunk, StructureLayer, chunk_of_keys
from glmap_tools.map.units import InstanceUnit, RegionUnit

MAX_ID = 1 << 53  # ids and frame indices stay exact as JSON numbers
MAX_COORDINATE = 1e6  # m; a Gaussian mean or camera farther out is not a map of a place
MAX_EMBEDDING_DIM = 65536
EMBEDDING_LENGTH_TOLERANCE = 1e-3  # float32 unit vectors are within ~1e-6 of length 1
# Sane ranges of stored settings: (low, high) inclusive. A 1e-9 m cell would make the
# index grid of a single Gaussian billions of cells.
CONFIG_RANGES = {
    "voxel_size": (0.002, 1.0),
    "cell_size": (0.01, 5.0),
    "max_range": (0.1, 1000.0),
    "camera_height": (0.01, 10.0),
    "occupancy_stride": (1, 64),
    "structure_stride": (0, 64),
    "max_text_words": (10, 1_000_000),
}
STRUCTURE_VOXEL_RANGE = (0.01, 1.0)

_UNIT_ROW = "embedding means covs colors opacities counts observations first_frame last_frame"
COLUMNS: dict[str, tuple[str, ...]] = {
    table: tuple(names.split())
    for table, names in {
        "meta": "key value",
        "instances": "id label text " + _UNIT_ROW,
        "regions": "id text embedding instance_ids observations first_frame last_frame",
        "occupancy": "ci cj counts",
        "frames": "seq frame_index pose",
        "structure": "ci cj keys means covs colors opacities counts",
    }.items()
}
TABLES_OF_VERSION = {
    1: ("meta", "instances", "regions", "occupancy", "frames"),
    2: ("meta", "instances", "regions", "occupancy", "frames", "structure"),
}


class InvalidStoreError(StoreError):
    """A map file whose tables or contents are not those of a valid GLMap store."""


@dataclass
class StoredState:
    """Everything a map file holds, checked, ready for `GLMap._restore`."""

    instances: dict[int, InstanceUnit]
    regions: dict[int, RegionUnit]
    occupancy: OccupancyGrid
    structure: StructureLayer
    next_id: int
    floor_z: float | None
    trajectory: list[np.ndarray]  # [4, 4] each
    embedder: str | None
    embedding_dim: int | None


class Refuser:
    """Builds the refusal for one file."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __call__(self, what: str) -> InvalidStoreError:
        return InvalidStoreError(
            f"{self.path!r} is not a valid GLMap store: {what}. Nothing was loaded and the "
            "file was not changed; open another map file or restore this one from a copy."
        )


# ---------------------------------------------------------------------- scalars


def check_int(refuse: Refuser, value: object, what: str, low: int = -MAX_ID) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise refuse(f"{what} is {_show(value)}, not an integer")
    if not low <= value < MAX_ID:
        raise refuse(f"{what} is {value}, outside {low}..{MAX_ID - 1}")
    return value


def check_text(refuse: Refuser, value: object, what: str) -> str:
    if not isinstance(value, str):
        raise refuse(f"{what} is {_show(value)}, not text")
    return value


def parse_json(refuse: Refuser, value: object, what: str) -> Any:
    text = check_text(refuse, value, what)
    try:
        return json.loads(text)
    except (ValueError, RecursionError):
        raise refuse(f"{what} is not JSON: {_show(text)}") from None


def parse_digits(value: object) -> int | None:
    """A meta value written as ASCII decimal digits (at most 18), or None."""
    if isinstance(value, str) and value.isascii() and value.isdigit() and len(value) <= 18:
        return int(value)
    return None


def _show(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# ---------------------------------------------------------------------- arrays


def read_array(
    refuse: Refuser, blob: object, what: str, dtype: str, shape: tuple[int | None, ...]
) -> np.ndarray:
    """A .npy blob as an array, checked before its data is read.

    Args:
        dtype: the only dtype accepted, e.g. "<f4".
        shape: expected shape; None matches any length (at most 2**31 - 1).

    Raises:
        InvalidStoreError: not bytes, not .npy, another dtype or shape, or a byte length
            that does not match the header.
    """
    if not isinstance(blob, bytes):
        raise refuse(f"{what} is {_show(blob)}, not an array blob")
    f = io.BytesIO(blob)
    try:
        major, _ = np.lib.format.read_magic(f)
        read_header = (
            np.lib.format.read_array_header_1_0
            if major == 1
            else np.lib.format.read_array_header_2_0
        )
        got_shape, fortran, got_dtype = read_header(f)
    except Exception:  # numpy parses untrusted header text: it raises many kinds
        raise refuse(f"{what} is not a .npy array blob") from None
    if got_dtype != np.dtype(dtype) or got_dtype.hasobject:
        raise refuse(f"{what} has dtype {got_dtype}, not {np.dtype(dtype)}")
    if fortran or len(got_shape) != len(shape):
        raise refuse(f"{what} has shape {got_shape}, not {_shape_text(shape)}")
    for got, want in zip(got_shape, shape, strict=True):
        if (want is not None and got != want) or not 0 <= got < 1 << 31:
            raise refuse(f"{what} has shape {got_shape}, not {_shape_text(shape)}")
    data = blob[f.tell() :]
    expected = math.prod(got_shape) * got_dtype.itemsize
    if len(data) != expected:
        raise refuse(f"{what} holds {len(data)} bytes of data; its header needs {expected}")
    return np.frombuffer(bytearray(data), dtype=got_dtype).reshape(got_shape)


def _shape_text(shape: tuple[int | None, ...]) -> str:
    return "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"


def read_gaussians(refuse: Refuser, blobs: tuple[object, ...], what: str) -> GaussianSet:
    """Five blobs (means, covs, colors, opacities, counts) as a checked GaussianSet (N >= 1)."""
    means = read_array(refuse, blobs[0], f"{what} means", "<f4", (None, 3))
    n = len(means)
    covs = read_array(refuse, blobs[1], f"{what} covs", "<f4", (n, 3, 3))
    colors = read_array(refuse, blobs[2], f"{what} colors", "<f4", (n, 3))
    opacities = read_array(refuse, blobs[3], f"{what} opacities", "<f4", (n,))
    counts = read_array(refuse, blobs[4], f"{what} counts", "<u4", (n,))
    if n == 0:
        raise refuse(f"{what} has no Gaussians")
    if not (np.isfinite(means).all() and np.abs(means).max() <= MAX_COORDINATE):
        raise refuse(f"{what} means are not finite coordinates within {MAX_COORDINATE:g} m")
    c64 = covs.astype(np.float64)
    if not np.isfinite(c64).all() or np.abs(c64 - c64.transpose(0, 2, 1)).max() > 1e-6:
        raise refuse(f"{what} covs are not finite symmetric matrices")
    if np.linalg.eigvalsh(c64).min() <= 0 or c64.max() > MAX_COORDINATE:
        raise refuse(f"{what} covs are not positive definite covariances")
    if not (np.isfinite(colors).all() and colors.min() >= 0 and colors.max() <= 1):
        raise refuse(f"{what} colors are not RGB values in [0, 1]")
    if not (np.isfinite(opacities).all() and opacities.min() > 0 and opacities.max() <= 1):
        raise refuse(f"{what} opacities are not in (0, 1]")
    if counts.min() < 1:
        raise refuse(f"{what} has a Gaussian with count 0")
    return GaussianSet(means, covs, colors, opacities, counts)


def read_embedding(refuse: Refuser, blob: object, what: str, dim: int | None) -> np.ndarray:
    e = read_array(refuse, blob, what, "<f4", (dim,))
    if not 1 <= len(e) <= MAX_EMBEDDING_DIM or not np.isfinite(e).all():
        raise refuse(f"{what} is not a finite vector of 1..{MAX_EMBEDDING_DIM} numbers")
    # Units keep unit vectors (or zero ones); search scores are dot products, so cosines.
    length = float(np.linalg.norm(e.astype(np.float64)))  # float64: squares of 1e30 fit
    if length != 0.0 and abs(length - 1.0) > EMBEDDING_LENGTH_TOLERANCE:
        raise refuse(f"{what} has length {length:.6g}, not 1 (units keep unit vectors)")
    return e


# ---------------------------------------------------------------------- tables


def check_tables(refuse: Refuser, conn: sqlite3.Connection, version: int) -> None:
    """Every table of the schema version exists with exactly its columns, and no table of a
    later version does (an upgrade would create it again)."""
    for table in TABLES_OF_VERSION[version]:
        columns = tuple(row[1] for row in conn.execute(f"PRAGMA table_info({table})"))
        if not columns:
            raise refuse(f"table {table!r} is missing")
        if columns != COLUMNS[table]:
            raise refuse(f"table {table!r} has columns {list(columns)}, not {list(COLUMNS[table])}")
    for table in sorted(set(COLUMNS) - set(TABLES_OF_VERSION[version])):
        if conn.execute(f"PRAGMA table_info({table})").fetchone() is not None:
            raise refuse(f"it holds a {table!r} table, which schema version {version} has not")


def parse_version(refuse: Refuser, meta: dict[Any, Any], newest: int) -> int:
    raw = meta.get("schema_version")
    version = parse_digits(raw)
    if version is None or version < 1:
        raise refuse(f"schema_version is {_show(raw)}, not a version number 1..{newest}")
    if version > newest:
        raise StoreError(
            f"{refuse.path!r} has schema version {version}; this glmap-tools reads up to "
            f"{newest}. Upgrade glmap-tools."
        )
    return version


def parse_config(refuse: Refuser, meta: dict[Any, Any]) -> MapConfig:
    """The stored MapConfig: JSON, schema-checked by pydantic, then range-checked."""
    if "config" not in meta:
        raise refuse("the meta table has no config")
    data = parse_json(refuse, meta["config"], "the config")
    if not isinstance(data, dict):
        raise refuse(f"the config is {_show(data)}, not a JSON object")
    known = {f.name for f in dataclasses.fields(MapConfig)}
    if set(data) - known:
        raise refuse(f"the config has unknown keys {sorted(set(data) - known)}")
    try:
        config = TypeAdapter(MapConfig).validate_python(data)
    except (ValidationError, GLMapError, TypeError, ValueError) as exc:
        first = str(exc).splitlines()
        raise refuse(f"the config does not fit MapConfig ({' '.join(first[:3])})") from None
    for name, (low, high) in CONFIG_RANGES.items():
        value = getattr(config, name)
        if not (isinstance(value, int | float) and low <= value <= high):
            raise refuse(f"config {name}={_show(value)} is outside [{low}, {high}]")
    sv = config.structure_voxel
    if sv is not None and not STRUCTURE_VOXEL_RANGE[0] <= sv <= STRUCTURE_VOXEL_RANGE[1]:
        raise refuse(f"config structure_voxel={sv!r} is outside {list(STRUCTURE_VOXEL_RANGE)}")
    low, high = config.obstacle_band
    if high > 10.0 or (config.floor_z is not None and not abs(config.floor_z) <= MAX_COORDINATE):
        raise refuse("config obstacle_band or floor_z is out of range")
    if config.tau_s is not None and not math.isfinite(config.tau_s):
        raise refuse(f"config tau_s={config.tau_s!r} is not finite")
    try:
        EstimatorConfig(voxel_size=config.voxel_size, **config.estimator)
    except (GLMapError, TypeError) as exc:
        raise refuse(f"config estimator={_show(config.estimator)} is invalid ({exc})") from None
    return config


def _read_units(
    refuse: Refuser, conn: sqlite3.Connection, dim: int | None
) -> tuple[dict[int, InstanceUnit], dict[int, RegionUnit]]:
    instances: dict[int, InstanceUnit] = {}
    for row in conn.execute(f"SELECT {', '.join(COLUMNS['instances'])} FROM instances"):
        uid = check_int(refuse, row[0], "an instance id", 1)
        what = f"instance {uid}"
        label = check_text(refuse, row[1], f"{what} label")
        text = check_text(refuse, row[2], f"{what} text")
        e = read_embedding(refuse, row[3], f"{what} embedding", dim)
        dim = len(e)
        g = read_gaussians(refuse, row[4:9], what)
        obs, first, last = (check_int(refuse, v, f"{what} observations/frames") for v in row[9:12])
        if obs < 1 or first > last:
            raise refuse(f"{what} has {obs} observations, frames {first}..{last}")
        instances[uid] = InstanceUnit(uid, label, text, e, g, obs, first, last)
    regions: dict[int, RegionUnit] = {}
    for row in conn.execute(f"SELECT {', '.join(COLUMNS['regions'])} FROM regions"):
        rid = check_int(refuse, row[0], "a region id", 1)
        what = f"region {rid}"
        if rid in instances:
            raise refuse(f"id {rid} is both an instance and a region")
        text = check_text(refuse, row[1], f"{what} text")
        e = read_embedding(refuse, row[2], f"{what} embedding", dim)
        dim = len(e)
        members = parse_json(refuse, row[3], f"{what} instance_ids")
        if not (
            isinstance(members, list)
            and members
            and all(isinstance(m, int) and not isinstance(m, bool) for m in members)
            and members == sorted(set(members))
        ):
            raise refuse(f"{what} instance_ids {_show(members)} is not a sorted list of ids")
        dangling = [m for m in members if m not in instances]
        if dangling:
            raise refuse(f"{what} names instances {dangling[:5]} that do not exist")
        obs, first, last = (check_int(refuse, v, f"{what} observations/frames") for v in row[4:7])
        if obs < 1 or first > last:
            raise refuse(f"{what} has {obs} observations, frames {first}..{last}")
        regions[rid] = RegionUnit(rid, text, e, tuple(members), obs, first, last)
    return instances, regions


def _read_layers(
    refuse: Refuser, conn: sqlite3.Connection, config: MapConfig, version: int
) -> tuple[OccupancyGrid, StructureLayer, list[np.ndarray]]:
    limit = MAX_COORDINATE / config.cell_size / OCC_CHUNK
    occupancy = OccupancyGrid(config.cell_size)
    for ci, cj, blob in conn.execute("SELECT ci, cj, counts FROM occupancy"):
        key = tuple(check_int(refuse, v, "an occupancy chunk key") for v in (ci, cj))
        what = f"occupancy chunk {key}"
        if max(abs(key[0]), abs(key[1])) > limit:
            raise refuse(f"{what} lies beyond {MAX_COORDINATE:g} m")
        counts = read_array(refuse, blob, what, "<i4", (2, OCC_CHUNK, OCC_CHUNK))
        if counts.min() < 0:
            raise refuse(f"{what} has negative counts")
        occupancy.chunks[(key[0], key[1])] = counts
    structure = StructureLayer(config.structure_voxel or config.voxel_size)
    if version >= 2:
        chunks: dict[tuple[int, int], StructureChunk] = {}
        for row in conn.execute(f"SELECT {', '.join(COLUMNS['structure'])} FROM structure"):
            key = tuple(check_int(refuse, v, "a structure chunk key") for v in row[:2])
            what = f"structure chunk {key}"
            if config.structure_voxel is None:
                raise refuse(f"{what} is stored but the config has no structure_voxel")
            g = read_gaussians(refuse, row[3:8], what)
            keys = read_array(refuse, row[2], f"{what} keys", "<i8", (len(g), 3))
            sorted_rows = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
            unique = len(keys) < 2 or np.any(np.diff(keys, axis=0) != 0, axis=1).all()
            if not (
                np.array_equal(sorted_rows, np.arange(len(keys)))
                and unique
                and (chunk_of_keys(keys) == key).all()
            ):
                raise refuse(f"{what} keys are not unique sorted voxels of that chunk")
            chunks[(key[0], key[1])] = StructureChunk(keys, g)
        structure.apply(chunks)
    trajectory = []
    for seq, index, blob in conn.execute("SELECT seq, frame_index, pose FROM frames ORDER BY seq"):
        check_int(refuse, seq, "a frame seq")
        check_int(refuse, index, f"frame {seq} index")
        pose = read_array(refuse, blob, f"frame {seq} pose", "<f8", (4, 4))
        ok = bool(np.isfinite(pose).all() and np.abs(pose).max() <= MAX_COORDINATE)
        try:
            ok = ok and bool(Pose(pose).matrix is not None)  # Pose raises unless rigid
        except GLMapError:
            ok = False
        if not ok:
            raise refuse(f"frame {seq} pose is not a rigid world_from_camera matrix")
        centre = pose[:3, 3]
        if np.abs(centre).max() > config.world_limit:  # no frame past it was integrated
            raise refuse(
                f"frame {seq} pose puts the camera at {np.abs(centre).max():.4g} m from the "
                f"origin, past the map's world_limit ({config.world_limit:g} m)"
            )
        trajectory.append(pose)
    if trajectory:
        centres = np.array([p[:3, 3] for p in trajectory])
        span = float((centres.max(axis=0) - centres.min(axis=0)).max())
        if span > config.max_span:
            raise refuse(
                f"the frames' camera centres span {span:.4g} m, more than the map's "
                f"max_span ({config.max_span:g} m)"
            )
    return occupancy, structure, trajectory


def read_state(
    refuse: Refuser, conn: sqlite3.Connection, meta: dict[Any, Any], config: MapConfig, version: int
) -> StoredState:
    """Read and check every table of an opened store (see the module docstring)."""
    try:
        check_tables(refuse, conn, version)
        dim = None
        if "embedding_dim" in meta:
            raw = parse_digits(meta["embedding_dim"])
            if raw is None:
                raise refuse(f"embedding_dim is {_show(meta['embedding_dim'])}, not a number")
            dim = check_int(refuse, raw, "embedding_dim", 1)
        embedder = meta.get("embedder")
        if embedder is not None:
            check_text(refuse, embedder, "the embedder name")
        instances, regions = _read_units(refuse, conn, dim)
        occupancy, structure, trajectory = _read_layers(refuse, conn, config, version)
    except sqlite3.Error as exc:
        raise refuse(f"SQLite cannot read it ({exc})") from None
    raw_next = parse_digits(meta.get("next_id", "1"))
    if raw_next is None:
        raise refuse(f"next_id is {_show(meta.get('next_id'))}, not a positive integer")
    next_id = check_int(refuse, raw_next, "next_id", 1)
    top = max([*instances, *regions], default=0)
    if next_id <= top:
        raise refuse(f"next_id {next_id} is not above the largest unit id {top}")
    floor_z = parse_json(refuse, meta.get("floor_z", "null"), "floor_z")
    if floor_z is not None and not (
        isinstance(floor_z, int | float)
        and not isinstance(floor_z, bool)
        and abs(floor_z) <= MAX_COORDINATE
    ):
        raise refuse(f"floor_z is {_show(floor_z)}, not a height in metres")
    return StoredState(
        instances,
        regions,
        occupancy,
        structure,
        next_id,
        None if floor_z is None else float(floor_z),
        trajectory,
        embedder,
        dim,
    )
