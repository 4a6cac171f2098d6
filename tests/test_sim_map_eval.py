"""A GLMap built from a simulated tour has about one instance per visible object."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import pytest

from glmap_tools.sim.render import CameraSpec
from glmap_tools.worlds.generator import generate_apartment
from glmap_tools.worlds.map_eval import build_map_from_tour, evaluate_instances

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


def test_map_eval_reports_duplicate_instances_and_duplicate_regions() -> None:
    import dataclasses

    from glmap_tools.worlds.map_eval import duplicate_regions

    layout = generate_apartment(5, n_rooms=3)
    glmap = map_module.GLMap(embedder=embed.HashingEmbedder())
    seen = build_map_from_tour(layout, glmap, CameraSpec(160, 120), max_frames=6)
    clean = evaluate_instances(glmap, layout, seen)
    assert clean.duplicate_instances == {} and clean.matched
    inst_id, obj_id = next(iter(clean.matched.items()))
    # A second copy of a matched instance (as a map that failed to merge would hold).
    copy_id = max([*glmap.instances, *glmap.regions]) + 1
    glmap.instances[copy_id] = dataclasses.replace(glmap.instances[inst_id], id=copy_id)
    result = evaluate_instances(glmap, layout, seen)
    assert result.duplicate_instances == {obj_id: [copy_id]}
    assert copy_id in result.spurious and result.precision < clean.precision
    dining, other = glmap.embedder.embed(["dining area: a table and chairs", "zebra crossing"])
    region = map_module.RegionUnit(
        id=copy_id + 1, text="dining area: a table and chairs", embedding=dining,
        instance_ids=(copy_id,), observations=1, first_frame=0, last_frame=0,
    )  # fmt: skip
    glmap.regions[copy_id + 1] = region
    # The same description and an overlapping member set: a duplicate.
    glmap.regions[copy_id + 2] = dataclasses.replace(
        region, id=copy_id + 2, instance_ids=(copy_id, copy_id + 10)
    )
    # Another description, or no shared member: not a duplicate.
    glmap.regions[copy_id + 3] = dataclasses.replace(
        region, id=copy_id + 3, text="zebra crossing", embedding=other
    )
    glmap.regions[copy_id + 4] = dataclasses.replace(region, id=copy_id + 4, instance_ids=(-1,))
    assert duplicate_regions(glmap) == [[copy_id + 1, copy_id + 2]]
