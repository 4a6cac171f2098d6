"""Procedural apartments: determinism, sizes, placement rules, reachability."""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.layout_io import layout_from_dict, layout_to_dict
from glmap_tools.sim.navgrid import build_nav_grid
from glmap_tools.worlds.generator import generate_apartment

SEEDS = [0, 3, 7, 12, 21]


@pytest.fixture(scope="module")
def apartments():
    return {seed: generate_apartment(seed) for seed in SEEDS}


def test_the_same_seed_gives_the_same_layout_and_another_seed_another() -> None:
    a, b, c = (layout_to_dict(generate_apartment(s)) for s in (5, 5, 6))
    assert a == b
    assert a != c


def test_apartments_have_3_to_7_rooms_and_25_to_80_objects(apartments) -> None:
    for layout in apartments.values():
        assert 3 <= len(layout.rooms) <= 7
        assert 25 <= len(layout.objects) <= 80
        assert layout.regions, "every apartment has functional regions"
    assert {len(a.rooms) for a in apartments.values()} != {len(apartments[0].rooms)}


def test_room_count_can_be_chosen() -> None:
    assert len(generate_apartment(2, n_rooms=7).rooms) == 7
    with pytest.raises(InvalidInputError, match="n_rooms=9"):
        generate_apartment(2, n_rooms=9)


def test_a_generated_layout_passes_validation_after_a_json_round_trip(apartments) -> None:
    data = layout_to_dict(apartments[7])
    assert layout_to_dict(layout_from_dict(data)) == data


def test_rooms_have_distinct_wall_colours(apartments) -> None:
    for layout in apartments.values():
        colours = [r.wall_color for r in layout.rooms]
        assert len(set(colours)) == len(colours)


def test_common_categories_have_several_instances_with_different_attributes(apartments) -> None:
    layout = apartments[7]  # seven rooms
    by_category = collections.defaultdict(list)
    for obj in layout.objects:
        by_category[obj.category].append(obj)
    multi = {c: objs for c, objs in by_category.items() if len(objs) >= 2}
    assert {"chair", "plant"} <= set(multi)
    for category in ("plant", "picture", "trash can"):
        objs = by_category.get(category, [])
        if len(objs) >= 2:
            assert len({o.description for o in objs}) >= 2, category


def test_chairs_around_a_table_face_it(apartments) -> None:
    seen = 0
    for layout in apartments.values():
        for region in layout.regions:
            members = [layout.object(i) for i in region.members]
            tables = [m for m in members if m.category == "table"]
            if not tables:
                continue
            table = tables[0]
            for chair in (m for m in members if m.category == "chair"):
                seen += 1
                assert table.distance_to(chair.position[:2])[0] < 0.3
                facing = np.array([math.cos(chair.heading), math.sin(chair.heading)])
                assert table.distance_to(chair.position[:2] + 0.45 * facing)[0] == 0.0
    assert seen >= 4


def test_the_tv_stands_on_its_stand_and_the_sofa_looks_towards_it(apartments) -> None:
    checked = 0
    for layout in apartments.values():
        tvs = [o for o in layout.objects if o.category == "tv"]
        sofas = [o for o in layout.objects if o.category == "sofa"]
        for tv in tvs:
            stand = layout.object(tv.supported_by)
            assert stand.category == "tv stand"
            assert tv.position[2] == pytest.approx(stand.top, abs=1e-3)
            sofa = sofas[0]
            to_tv = tv.position[:2] - sofa.position[:2]
            front = np.array([math.cos(sofa.heading), math.sin(sofa.heading)])
            checked += int(front @ to_tv / np.linalg.norm(to_tv) > 0.5)
    assert checked >= 4


def test_sinks_and_toilets_are_in_kitchens_and_bathrooms(apartments) -> None:
    for layout in apartments.values():
        for obj in layout.objects:
            room = layout.room(obj.room).type
            if obj.category == "sink":
                assert room in ("kitchen", "bathroom")
            if obj.category in ("toilet", "bathtub"):
                assert room == "bathroom"
            if obj.category in ("stove", "refrigerator"):
                assert room == "kitchen"


def test_every_room_has_navigable_floor_connected_to_the_others(apartments) -> None:
    for layout in apartments.values():
        grid = build_nav_grid(layout)
        xs, ys = grid.cell_centers()
        pts = np.column_stack([xs.ravel(), ys.ravel()])
        for room in layout.rooms:
            inside = room.contains(pts) & grid.navigable.ravel()
            assert inside.sum() * grid.cell**2 > 0.6, (layout.name, room.name)


def test_objects_on_top_of_others_rest_on_their_support(apartments) -> None:
    for layout in apartments.values():
        for obj in layout.objects:
            if obj.supported_by is not None:
                support = layout.object(obj.supported_by)
                assert obj.position[2] == pytest.approx(support.top, abs=1e-3)
                assert support.distance_to(obj.position[:2])[0] < 1e-6
