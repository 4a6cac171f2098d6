"""`from-scan` says which passages the agent cannot pass (issue 40): a study of our own whose
desk and shelves leave a gap to the reading corner behind them."""

from __future__ import annotations

import warnings

import pytest

from glmap_tools.sim.layout import LayoutWarning
from glmap_tools.worlds.scan import layout_from_scan, narrow_passages


def study(gap: float) -> dict:
    """A 4 m x 4 m study; a desk from the left wall and shelves from the right wall across
    its middle, `gap` metres apart; an armchair in the corner behind them."""
    desk_w = 1.7
    shelf_lo = 0.05 + desk_w + gap
    shelf_w = 3.95 - shelf_lo
    objects = [
        {"category": "desk", "center": [0.05 + desk_w / 2, 2.0, 0.375],
         "size": [desk_w, 0.5, 0.75]},
        {"category": "shelf", "center": [shelf_lo + shelf_w / 2, 2.0, 0.9],
         "size": [shelf_w, 0.5, 1.8]},
        {"category": "armchair", "center": [3.2, 3.3, 0.45], "size": [0.8, 0.8, 0.9]},
        {"category": "chair", "center": [1.0, 1.2, 0.45], "size": [0.45, 0.5, 0.9]},
    ]  # fmt: skip
    room = {"type": "office", "polygon": [[0, 0], [4, 0], [4, 4], [0, 4]]}
    return {"up": "z", "name": f"study-{gap}", "room": room, "objects": objects}


def test_a_corner_behind_a_narrow_gap_is_named_as_impassable() -> None:
    with pytest.warns(LayoutWarning) as said:
        layout = layout_from_scan(study(0.45), use_meshes=False)
    texts = [str(w.message) for w in said if "passage narrower" in str(w.message)]
    assert len(texts) == 1
    assert "in room 1 ('office')" in texts[0] and "cannot be expected to pass it" in texts[0]
    assert narrow_passages(layout) == texts


def test_a_gap_the_agent_passes_is_not_named() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LayoutWarning)
        layout = layout_from_scan(study(0.9), use_meshes=False)
    assert narrow_passages(layout) == []
