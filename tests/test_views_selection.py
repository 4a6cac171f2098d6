"""View selection (paper §3.2): agent height, free space, the least occluded side."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics
from glmap_tools.map import FREE, OBSTACLE, OccupancyGrid
from glmap_tools.map.occupancy import CHUNK
from glmap_tools.views import (
    NoFreeViewpointError,
    SelectionConfig,
    render_selected_view,
    select_view,
    view_intrinsics,
)
from glmap_tools.views.visibility import facing
from tests.test_views_fixtures import CHAIR_XY, WALL_Y, build_wall_scene, empty_map


@pytest.fixture(scope="module")
def scene():
    return build_wall_scene()


@pytest.fixture(scope="module")
def chair_choice(scene):
    return select_view(scene.glmap, scene.chair)


def test_an_object_behind_a_wall_is_rendered_from_the_open_side(scene, chair_choice):
    choice = chair_choice
    assert choice.placement == "free" and not choice.fallback
    assert choice.chosen.y > WALL_Y + 0.5  # the chair's side of the wall
    assert choice.visible > 0.9
    view, again = render_selected_view(scene.glmap, scene.chair, view_intrinsics(96, 72))
    assert again.chosen == choice.chosen  # the view does not depend on the output size
    red = (view.rgb[..., 0] > 150) & (view.rgb[..., 1] < 100)
    assert red.mean() > 0.05, "the red chair fills a good part of the image"
    assert view.label == "instance 1 (chair)"


def test_candidates_behind_the_wall_see_little_of_the_chair(chair_choice):
    scored = [c for c in chair_choice.candidates if c.score is not None]
    behind = [c for c in scored if c.y < WALL_Y - 0.3]
    open_side = [c for c in scored if c.y > CHAIR_XY[1]]
    assert len(behind) >= 5 and len(open_side) >= 5  # free space seen on both sides
    assert max(c.visible for c in behind) < 0.2
    assert np.median([c.visible for c in open_side]) > 0.9
    assert max(c.score for c in behind) < min(c.score for c in open_side)
    assert all(c.in_view > 0.9 for c in behind)  # in the frame, but hidden by the wall


def test_scored_candidates_stand_in_seen_free_space_clear_of_obstacles(scene, chair_choice):
    dense = scene.glmap.occupancy.to_dense()
    rows, cols = np.nonzero(dense.state == OBSTACLE)
    obstacles = np.array([dense.index_to_world(r, c) for r, c in zip(rows, cols, strict=True)])
    radius = SelectionConfig().agent_radius
    for c in chair_choice.candidates:
        if c.placement != "free":
            continue
        assert scene.glmap.occupancy.state_at(c.x, c.y) == FREE
        assert np.hypot(*(obstacles - [c.x, c.y]).T).min() >= radius


def test_the_camera_is_at_agent_height_and_faces_the_target(scene, chair_choice):
    c = chair_choice.chosen
    assert c.z == pytest.approx(scene.glmap.floor_z + scene.glmap.config.camera_height)
    forward = chair_choice.pose.rotation[:, 2]
    toward = np.array(CHAIR_XY) - [c.x, c.y]
    assert math.degrees(abs(math.atan2(forward[1], forward[0]) - math.atan2(*toward[::-1]))) < 3
    # The chair is low (up to 0.9 m): the camera pitches down, within the 30 degree cap.
    assert 0.0 < math.degrees(c.pitch) <= 30.0 + 1e-9
    assert forward[2] == pytest.approx(-math.sin(c.pitch))


def test_a_tall_wall_is_viewed_level(scene):
    choice = select_view(scene.glmap, scene.walls[0])
    assert math.degrees(choice.chosen.pitch) < 15.0


def test_view_selection_is_deterministic(scene, chair_choice):
    again = select_view(scene.glmap, scene.chair)
    assert again.candidates == chair_choice.candidates
    np.testing.assert_array_equal(again.pose.matrix, chair_choice.pose.matrix)


def test_a_region_is_framed_like_its_instances(scene):
    assert scene.region is not None
    choice = select_view(scene.glmap, scene.region)
    assert choice.label == f"region {scene.region}" and choice.chosen.y > WALL_Y + 0.5


def test_trajectory_cameras_within_reach_are_candidates(chair_choice):
    spots = [c for c in chair_choice.candidates if c.source == "trajectory"]
    assert len(spots) == 6  # every frame's camera is within max_distance of the chair
    assert all(c.ring == spots[0].ring for c in spots)


def test_without_seen_free_space_the_view_falls_back_and_says_so():
    scene = build_wall_scene()
    scene.glmap.occupancy = OccupancyGrid(scene.glmap.config.cell_size)  # nothing observed
    config = SelectionConfig(max_trajectory_candidates=0)
    choice = select_view(scene.glmap, scene.chair, config=config)
    assert choice.fallback and choice.placement == "unobserved"
    assert "FALLBACK" in choice.note
    assert choice.visible > 0.9  # still the view that sees the chair
    with pytest.raises(NoFreeViewpointError, match="require_free"):
        select_view(scene.glmap, scene.chair, config=config, require_free=True)
    assert issubclass(NoFreeViewpointError, GLMapError)


def test_when_every_spot_is_an_obstacle_the_best_blocked_view_is_flagged():
    scene = build_wall_scene()
    grid = OccupancyGrid(scene.glmap.config.cell_size)
    for ci in range(-3, 3):
        for cj in range(-3, 3):
            chunk = np.zeros((2, CHUNK, CHUNK), dtype=np.int32)
            chunk[1] = 1
            grid.chunks[(ci, cj)] = chunk
    scene.glmap.occupancy = grid
    choice = select_view(scene.glmap, scene.chair)
    assert choice.placement == "blocked" and choice.fallback
    assert all(c.score is not None for c in choice.candidates)


def test_selecting_a_view_in_an_empty_map_or_of_an_unknown_unit_says_so(scene):
    with pytest.raises(GLMapError, match="the map is empty"):
        select_view(empty_map(), 1)
    with pytest.raises(GLMapError, match="does not exist"):
        select_view(scene.glmap, 4242)
    wide = Intrinsics(1000.0, 1000.0, 2999.5, 4.5, 6000, 10)  # a valid camera, over the cap
    with pytest.raises(InvalidInputError, match="pixels"):
        select_view(scene.glmap, scene.chair, wide)


def test_bad_selection_settings_are_refused():
    for bad in (
        {"angle_step_deg": 0.0},
        {"ring_scales": ()},
        {"min_distance": 3.0, "max_distance": 2.0},
        {"score_width": 4},
        {"near_tie": 1.5},
    ):
        with pytest.raises(InvalidInputError):
            SelectionConfig(**bad)


def facing_reference(gaussians: GaussianSet, eye: np.ndarray) -> np.ndarray:
    """Per Gaussian: det of the covariance projected onto the plane across the ray, as an
    explicit 2x2 matrix in an orthonormal basis of that plane, over its largest value."""
    out = []
    for mean, cov in zip(gaussians.means, gaussians.covs, strict=True):
        s = cov.astype(np.float64)
        r = mean.astype(np.float64) - eye
        r /= np.linalg.norm(r)
        helper = np.array([1.0, 0.0, 0.0]) if abs(r[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(r, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(r, e1)
        basis = np.stack([e1, e2], axis=1)  # [3, 2]
        projected = basis.T @ s @ basis
        lam = np.linalg.eigvalsh(s)
        out.append(math.sqrt(np.linalg.det(projected) / (lam[1] * lam[2])))
    return np.array(out)


@pytest.mark.parametrize(("n", "seed"), [(1, 0), (17, 1), (300, 2)])
def test_facing_matches_the_explicit_projection(n, seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    scales = rng.uniform(0.002, 0.05, (n, 3)) ** 2
    covs = np.einsum("nij,nj,nkj->nik", q, scales, q) + 1e-6 * np.eye(3)
    g = GaussianSet(
        rng.uniform(-1, 1, (n, 3)), covs, np.full((n, 3), 0.5), np.full(n, 0.8), np.ones(n)
    )
    eye = np.array([0.3, -2.5, 0.9])
    np.testing.assert_allclose(facing(g, eye), facing_reference(g, eye), rtol=1e-4, atol=1e-6)


def test_a_flat_gaussian_faces_a_camera_in_front_and_not_one_edge_on():
    cov = np.diag([0.03**2, 0.03**2, 1e-6])[None]  # a disc in the x-y plane
    g = GaussianSet(np.zeros((1, 3)), cov, np.full((1, 3), 0.5), np.ones(1), np.ones(1))
    assert facing(g, np.array([0.0, 0.0, 2.0]))[0] == pytest.approx(1.0, abs=1e-6)
    assert facing(g, np.array([2.0, 0.0, 0.0]))[0] < 0.05
