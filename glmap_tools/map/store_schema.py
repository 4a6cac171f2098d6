"""The tables of a GLMap store file (`MapStore`) and its schema versions.

Version 1 had no structure layer; version 2 adds the `structure` table (one row per chunk of
the structure background layer). A version-1 file opens as a map with an empty structure
layer, and becomes version 2 in the transaction of its first new frame. Arrays are stored as
.npy bytes (`store_rows.to_npy`), never pickled; the checked reader is `store_check.py`.
"""

from __future__ import annotations

FORMAT = "glmap-tools map"
SCHEMA_VERSION = 2
EXTRA_PREFIX = "extra."  # meta rows a caller keeps beside the map: `extra.<name>`

STRUCTURE_TABLE = """
CREATE TABLE structure (ci INTEGER NOT NULL, cj INTEGER NOT NULL, keys BLOB NOT NULL,
  means BLOB NOT NULL, covs BLOB NOT NULL, colors BLOB NOT NULL, opacities BLOB NOT NULL,
  counts BLOB NOT NULL, PRIMARY KEY (ci, cj));
"""

SCHEMA = (
    """
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE instances (
  id INTEGER PRIMARY KEY, label TEXT NOT NULL, text TEXT NOT NULL, embedding BLOB NOT NULL,
  means BLOB NOT NULL, covs BLOB NOT NULL, colors BLOB NOT NULL, opacities BLOB NOT NULL,
  counts BLOB NOT NULL, observations INTEGER NOT NULL, first_frame INTEGER NOT NULL,
  last_frame INTEGER NOT NULL);
CREATE TABLE regions (
  id INTEGER PRIMARY KEY, text TEXT NOT NULL, embedding BLOB NOT NULL,
  instance_ids TEXT NOT NULL, observations INTEGER NOT NULL, first_frame INTEGER NOT NULL,
  last_frame INTEGER NOT NULL);
CREATE TABLE occupancy (ci INTEGER NOT NULL, cj INTEGER NOT NULL, counts BLOB NOT NULL,
  PRIMARY KEY (ci, cj));
CREATE TABLE frames (seq INTEGER PRIMARY KEY, frame_index INTEGER NOT NULL, pose BLOB NOT NULL);
"""
    + STRUCTURE_TABLE
)

# How a row (store_rows.py) goes into its table; a frame's `seq` is SQLite's.
INSERT = {
    "instances": "INSERT OR REPLACE INTO instances VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
    "regions": "INSERT OR REPLACE INTO regions VALUES (?,?,?,?,?,?,?)",
    "occupancy": "INSERT OR REPLACE INTO occupancy VALUES (?,?,?)",
    "structure": "INSERT OR REPLACE INTO structure VALUES (?,?,?,?,?,?,?,?)",
    "frames": "INSERT INTO frames (frame_index, pose) VALUES (?, ?)",
}
