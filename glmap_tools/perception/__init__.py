"""Perception: from an RGB-D frame to `FrameSemantics` (annotated or model-backed)."""

from glmap_tools.perception.semantics import FrameSemantics, GroupObservation, ObjectObservation

__all__ = ["FrameSemantics", "GroupObservation", "ObjectObservation"]
