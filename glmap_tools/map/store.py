"""`MapStore`: a GLMap as one SQLite file (arrays as .npy bytes, never pickle).

Every `GLMap.integrate` commits in one transaction; reopening reproduces the map exactly.
The index grid is not stored: it is derived from the Gaussians on load, identically.
Opening checks the whole file (store_check.py) and refuses an invalid one.

A store may also carry *extras*: named JSON-text rows of the meta table (key `extra.<name>`)
that a caller keeps beside the map, e.g. the MCP server's simulator episode. An extra can
be staged to go into the next frame's transaction, so the two never disagree.

The tables and schema versions are in store_schema.py, units as rows in store_rows.py.
"""

from __future__ import annotations

import json
import os
import sqlite3
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from glmap_tools.errors import StoreError
from glmap_tools.map.config import MapConfig
from glmap_tools.map.store_check import (
    InvalidStoreError,
    Refuser,
    StoredState,
    parse_config,
    parse_version,
    read_state,
)
from glmap_tools.map.store_file import connect, fsync
from glmap_tools.map.store_rows import Row, map_rows, plan_rows
from glmap_tools.map.store_schema import (
    EXTRA_PREFIX,
    FORMAT,
    INSERT,
    SCHEMA,
    SCHEMA_VERSION,
    STRUCTURE_TABLE,
)

if TYPE_CHECKING:
    from glmap_tools.map.fusion import FramePlan
    from glmap_tools.map.state import MapState

__all__ = ["FORMAT", "SCHEMA_VERSION", "InvalidStoreError", "MapStore"]


class MapStore:
    """An open GLMap SQLite file.

    Attributes:
        version: the file's schema version (1 until its first commit, then SCHEMA_VERSION).
    """

    def __init__(
        self,
        path: Path,
        conn: sqlite3.Connection,
        config: MapConfig,
        version: int = SCHEMA_VERSION,
        state: StoredState | None = None,
    ) -> None:
        self.path = path
        self.conn = conn
        self.config = config
        self.version = version
        self._state = state
        self._staged: dict[str, str] = {}
        self._seen = self._fingerprint()

    # ------------------------------------------------------------- open / create
    @classmethod
    def open(cls, path: str | os.PathLike[str], create_with: MapConfig | None = None) -> MapStore:
        """Open an existing store, or create one with `create_with` if `path` does not exist.

        Raises:
            StoreError: not a GLMap store, a newer schema, or the path cannot be used.
        """
        path = _checked_path(path)
        if not path.exists():
            if create_with is None:
                raise StoreError(f"map file {str(path)!r} does not exist; check the path.")
            return cls._create(path, create_with)
        if path.is_dir():
            raise StoreError(f"{str(path)!r} is a directory; pass the path of a map file.")
        conn = connect(path)
        try:
            try:
                meta = dict(conn.execute("SELECT key, value FROM meta").fetchall())
            except (sqlite3.Error, ValueError) as exc:
                raise StoreError(
                    f"{str(path)!r} is not a GLMap store ({exc}); pass a .glmap file written "
                    "by glmap-tools, or a new path to create one."
                ) from None
            if meta.get("format") != FORMAT:
                raise StoreError(
                    f"{str(path)!r} is an SQLite file but not a GLMap store (no "
                    f"format={FORMAT!r} in its meta table); pass a .glmap file or a new path."
                )
            refuse = Refuser(str(path))
            version = parse_version(refuse, meta, SCHEMA_VERSION)
            config = parse_config(refuse, meta)
            state = read_state(refuse, conn, meta, config, version)
        except BaseException:
            conn.close()
            raise
        return cls(path, conn, config, version, state)

    @classmethod
    def _create(cls, path: Path, config: MapConfig, glmap: MapState | None = None) -> MapStore:
        if not path.parent.is_dir():
            raise StoreError(
                f"folder {str(path.parent)!r} does not exist; create it or choose another path."
            )
        # Build in a temporary file beside the target, then rename: no partial map files.
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        except OSError as exc:  # a read-only or immutable folder, a name too long, ...
            kept = "the old file is unchanged" if path.exists() else "no file was made"
            raise StoreError(
                f"cannot create a file in the folder {str(path.parent)!r} to write the map "
                f"file {path.name!r}: {exc.strerror or exc}; {kept}. Make the folder writable "
                "by the server (or choose another folder), then save again."
            ) from None
        os.close(fd)
        try:
            conn = connect(Path(tmp))
            with conn:
                conn.executescript(SCHEMA)
                store = cls(Path(tmp), conn, config)
                store._write_meta(
                    {
                        "format": FORMAT,
                        "schema_version": str(SCHEMA_VERSION),
                        "config": json.dumps(config.to_dict(), sort_keys=True),
                    }
                )
                if glmap is not None:
                    store._write_everything(glmap)
                else:
                    store._write_meta({"next_id": "1", "floor_z": json.dumps(config.floor_z)})
            conn.close()
            fsync(Path(tmp))
            os.replace(tmp, path)
        except BaseException as exc:  # no partial file: the target is the old one or none
            Path(tmp).unlink(missing_ok=True)
            if isinstance(exc, OSError | sqlite3.Error):
                why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
                kept = "the old file is unchanged" if path.exists() else "no file was made"
                raise StoreError(
                    f"could not write the map file {str(path)!r}: {why}; {kept}. Check disk "
                    "space and permissions, then save again."
                ) from None
            raise
        fsync(path.parent)  # the rename itself survives a crash
        return cls(path, connect(path), config, SCHEMA_VERSION)

    @classmethod
    def create_from(
        cls, path: str | os.PathLike[str], glmap: MapState, overwrite: bool = False
    ) -> MapStore:
        """Write all of `glmap` to a new file at `path` (atomically)."""
        path = _checked_path(path)
        if path.exists() and not overwrite:
            raise StoreError(
                f"{str(path)!r} already exists; choose a new path or pass overwrite=True."
            )
        return cls._create(path, glmap.config, glmap)

    def close(self) -> None:
        self.conn.close()

    # ------------------------------------------------------------- other writers
    def _fingerprint(self) -> tuple[int, int]:
        """(the file's inode, SQLite's data_version of this connection); -1 where unknown."""
        try:
            ino = os.stat(self.path).st_ino
        except OSError:
            ino = -1
        try:
            version = int(self.conn.execute("PRAGMA data_version").fetchone()[0])
        except sqlite3.Error:
            version = -1
        return ino, version

    def changed_elsewhere(self) -> bool:
        """Whether another connection committed to the file, or replaced it, since this one
        opened it or last called `mark_seen` (own commits do not count)."""
        return self._fingerprint() != self._seen

    def mark_seen(self) -> None:
        """Take the file as it is now as the state `changed_elsewhere` compares with."""
        self._seen = self._fingerprint()

    def damage(self) -> str | None:
        """What is wrong with the file on disk (missing, truncated, corrupt), or None if it
        passes SQLite's quick check; costs one read of the file."""
        if not self.path.is_file():
            return "the file is missing"
        try:
            rows = self.conn.execute("PRAGMA quick_check").fetchall()
        except sqlite3.Error as exc:
            return str(exc)
        problems = [str(r[0]) for r in rows if r and r[0] != "ok"]
        return "; ".join(problems[:3]) or None

    def _changed(self, frame_index: int) -> StoreError:
        return StoreError(
            f"{str(self.path)!r} was changed by another process since this map was read, so "
            f"frame {frame_index} was not written (the two maps would mix). Open the map again "
            "(glmap-mcp: load_map) to go on from what the file holds now."
        )

    # ------------------------------------------------------------- extras
    def read_extra(self, name: str) -> str | None:
        """The extra `name` as stored in the file now, or None."""
        row = self.conn.execute(
            "SELECT value FROM meta WHERE key = ?", (EXTRA_PREFIX + name,)
        ).fetchone()
        return None if row is None else str(row[0])

    def stage_extra(self, name: str, value: str) -> None:
        """Write the extra `name` in the transaction of the next `commit_frame`."""
        self._staged[EXTRA_PREFIX + name] = value

    def write_extra(self, name: str, value: str | None) -> None:
        """Write (or, with None, delete) the extra `name` now, in its own transaction.

        Raises:
            StoreError: the write failed; the file is unchanged.
        """
        key = EXTRA_PREFIX + name
        self._staged.pop(key, None)
        try:
            with self.conn:
                if value is None:
                    self.conn.execute("DELETE FROM meta WHERE key = ?", (key,))
                else:
                    self._write_meta({key: value})
        except sqlite3.Error as exc:
            raise StoreError(
                f"could not write {name} to {str(self.path)!r}: {exc}; the file is unchanged. "
                "Check disk space and permissions."
            ) from exc

    # ------------------------------------------------------------- writes
    def _write_meta(self, items: dict[str, str]) -> None:
        self.conn.executemany(
            "INSERT OR REPLACE INTO meta (key, value) VALUES (?, ?)", list(items.items())
        )

    def _insert(self, rows: dict[str, list[Row]], *tables: str) -> None:
        for table in tables:
            self.conn.executemany(INSERT[table], rows[table])

    def _migrate(self, glmap: MapState) -> None:
        """Upgrade a version-1 file to this schema, inside the caller's transaction."""
        if self.version == SCHEMA_VERSION:
            return
        self.conn.execute(STRUCTURE_TABLE)
        self._write_meta(
            {
                "schema_version": str(SCHEMA_VERSION),
                "config": json.dumps(glmap.config.to_dict(), sort_keys=True),
            }
        )

    def _write_embedder(self, glmap: MapState) -> None:
        self._write_meta(
            {"embedder": glmap.embedder.name, "embedding_dim": str(glmap.embedder.dim)}
        )

    def _write_everything(self, glmap: MapState) -> None:
        rows = map_rows(glmap)
        self._insert(rows, "instances", "regions", "occupancy", "structure", "frames")
        self._write_embedder(glmap)
        self._write_meta({"next_id": str(glmap.next_id), "floor_z": json.dumps(glmap.floor_z)})

    def commit_frame(self, plan: FramePlan, glmap: MapState) -> None:
        """Write one frame's changes in a single transaction (all or nothing).

        Raises:
            StoreError: the write failed, or another process changed or replaced the file
                since this store read it (writing would mix two maps); nothing was written.
        """
        if self._fingerprint()[0] != self._seen[0]:
            raise self._changed(plan.frame_index)
        rows = plan_rows(plan)
        try:
            with self.conn:
                # Take the write lock first, then check that no one else wrote meanwhile; the
                # migration's DDL is part of this transaction.
                self.conn.execute("BEGIN IMMEDIATE")
                if self._fingerprint()[1] != self._seen[1]:
                    raise self._changed(plan.frame_index)
                self._insert(rows, "frames")
                self._migrate(glmap)
                self._insert(rows, "instances", "regions")
                for table in ("instances", "regions"):  # units fused into an older one
                    self.conn.executemany(
                        f"DELETE FROM {table} WHERE id = ?", [(i,) for i in sorted(plan.removed)]
                    )
                self._insert(rows, "occupancy", "structure")
                self._write_embedder(glmap)
                self._write_meta(
                    {"next_id": str(plan.next_id), "floor_z": json.dumps(plan.floor_z)}
                )
                if self._staged:
                    self._write_meta(self._staged)
            self.version = SCHEMA_VERSION
            self._staged = {}
        except sqlite3.Error as exc:
            raise StoreError(
                f"could not write frame {plan.frame_index} to {str(self.path)!r}: {exc}; the "
                "file is unchanged. Check disk space and permissions."
            ) from exc

    # ------------------------------------------------------------- reads
    def load_into(self, glmap: MapState) -> None:
        """Install the checked contents of the file into a freshly constructed GLMap.

        Raises:
            StoreError: the map was built with another embedder (name or dimension).
        """
        state = self._state
        if state is None:
            meta = dict(self.conn.execute("SELECT key, value FROM meta").fetchall())
            state = read_state(Refuser(str(self.path)), self.conn, meta, self.config, self.version)
        name = state.embedder
        if name is not None and name != glmap.embedder.name:
            raise StoreError(
                f"{str(self.path)!r} was built with the embedder {name!r} but was opened with "
                f"{glmap.embedder.name!r}; open it with the same embedder (embeddings differ)."
            )
        dims = {len(u.embedding) for u in state.instances.values()}
        dims |= {len(r.embedding) for r in state.regions.values()}
        if dims - {glmap.embedder.dim}:
            raise InvalidStoreError(
                f"{str(self.path)!r} is not a valid GLMap store: its embeddings have "
                f"{sorted(dims)} numbers but the embedder {glmap.embedder.name!r} makes "
                f"{glmap.embedder.dim}. Nothing was loaded and the file was not changed."
            )
        self._state = None  # hand the arrays over; a second load reads the file again
        glmap._restore(
            state.instances,
            state.regions,
            state.occupancy,
            state.structure,
            state.next_id,
            state.floor_z,
            state.trajectory,
        )


def _checked_path(path: str | os.PathLike[str]) -> Path:
    """`path` as a Path; anything but a str or path, or a NUL character (no file system
    takes one), is refused."""
    if not isinstance(path, (str, os.PathLike)) or isinstance(path, bytes):
        raise StoreError(
            f"map path {path!r} ({type(path).__name__}) is no file name; give a str or a Path."
        )
    out = Path(path)
    if "\x00" in str(out):
        raise StoreError(
            f"map path {str(out)!r} holds a NUL character; give a file name without it."
        )
    return out
