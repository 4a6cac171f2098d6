"""Situated question answering on a GLMap (paper §3.2): locate a situation from text,
render four labelled views, and answer from the map (offline) or with an MLLM."""

from glmap_tools.sqa.situate import ScoredUnit, Situation, situate, split_situation

__all__ = ["ScoredUnit", "Situation", "situate", "split_situation"]
