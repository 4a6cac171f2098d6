"""Ingest: posed RGB-D sequences on disk (Redwood/Open3D, TUM RGB-D) and their annotations."""

from glmap_tools.ingest.datasets import FORMATS, IngestFrame, RGBDSequence, open_sequence
from glmap_tools.ingest.images import (
    load_depth_png,
    load_rgb,
    read_annotation,
    write_annotation,
)

__all__ = [
    "FORMATS",
    "IngestFrame",
    "RGBDSequence",
    "load_depth_png",
    "load_rgb",
    "open_sequence",
    "read_annotation",
    "write_annotation",
]
