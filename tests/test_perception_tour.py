"""map-eval with geometric perception: segments named by ground truth make a faithful map."""

from __future__ import annotations

from pathlib import Path

import pytest

import glmap_tools
from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap
from glmap_tools.sim.layout_io import load_layout
from glmap_tools.sim.render import CameraSpec
from glmap_tools.worlds.map_eval import build_map_from_tour, evaluate_instances

LAYOUT = Path(glmap_tools.__file__).parent / "data" / "benchmark" / "tune" / "s01" / "layout.json"


def test_a_geometric_tour_map_finds_most_objects_without_duplicates():
    layout = load_layout(LAYOUT)
    glmap = GLMap(embedder=HashingEmbedder())
    camera = CameraSpec(width=320, height=240)
    seen = build_map_from_tour(layout, glmap, camera, max_frames=10, perception="geometric")
    result = evaluate_instances(glmap, layout, seen)
    assert result.recall >= 0.7, result
    assert result.precision >= 0.7, result


def test_an_unknown_perception_is_refused_before_any_frame():
    glmap = GLMap(embedder=HashingEmbedder())
    with pytest.raises(InvalidInputError, match="'magic' is unknown"):
        build_map_from_tour(load_layout(LAYOUT), glmap, perception="magic")
    assert len(glmap.trajectory) == 0
