"""A GLMap built from a simulated tour has about one instance per visible object."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import pytest

from glmap_tools.sim.generator import generate_apartment
from glmap_tools.sim.map_eval import build_map_from_tour, evaluate_instances
from glmap_tools.sim.render import CameraSpec

map_module = pytest.importorskip("glmap_tools.map")
embed = pytest.importorskip("glmap_tools.language.embed")


@pytest.mark.slow
def test_a_tour_with_ground_truth_annotations_maps_each_visible_object_once() -> None:
    layout = generate_apartment(5, n_rooms=3)
    glmap = map_module.GLMap(embedder=embed.HashingEmbedder())
    seen = build_map_from_tour(layout, glmap, CameraSpec(480, 360))
    result = evaluate_instances(glmap, layout, seen)
    assert result.visible_objects >= 20
    assert result.recall >= 0.95, result.missed
    assert result.precision >= 0.85, result.spurious


def test_an_empty_map_has_zero_precision_and_recall() -> None:
    layout = generate_apartment(5, n_rooms=3)
    glmap = map_module.GLMap(embedder=embed.HashingEmbedder())
    result = evaluate_instances(glmap, layout, {o.id for o in layout.objects[:3]})
    assert (result.precision, result.recall, result.missed) == (0.0, 0.0, [1, 2, 3])
