"""The SQLite file of a map store on disk: connecting, flushing to the disk, and the folder
map files are made in. Every failure is a `StoreError` that names the path and the fix.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from glmap_tools.errors import StoreError


def make_folder(folder: Path) -> None:
    """Create `folder` (and its parents) for map files.

    Raises:
        StoreError: it cannot be created (a read-only or immutable parent, a file in the
            way); the message names it and the fix.
    """
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise StoreError(
            f"cannot create the folder {str(folder)!r} for map files: {exc.strerror or exc}. "
            "Create it, writable by the server, or choose another folder (--maps-dir)."
        ) from None


def fsync(path: Path) -> None:
    """Flush a file's (or a folder's) data to the disk; folders that cannot be opened pass."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        if path.is_dir():
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not path.is_dir():
            raise
    finally:
        os.close(fd)


def connect(path: Path) -> sqlite3.Connection:
    try:
        conn = sqlite3.connect(str(path), isolation_level="DEFERRED", check_same_thread=False)
        conn.execute("PRAGMA synchronous=NORMAL")
    except sqlite3.DatabaseError as exc:
        raise StoreError(
            f"{str(path)!r} is not a GLMap store ({exc}); pass a .glmap file written by "
            "glmap-tools, or a new path to create one."
        ) from None
    except sqlite3.Error as exc:
        raise StoreError(f"cannot open {str(path)!r} as a map file: {exc}.") from None
    return conn
