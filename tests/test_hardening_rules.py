"""Rules that tests with degenerate inputs did not pin (issue 41 item 7): each test names the
rule (the paper's, or a metric's definition) and uses an input where getting it wrong shows."""

from __future__ import annotations

import dataclasses
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np
import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.gaussians.render import render
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose, backproject
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig

# Real cameras have fx != fy (TUM's, any image resized to another aspect): every camera the
# other tests use has fx = fy, where swapping them changes nothing.
ANISOTROPIC = Intrinsics(600.0, 500.0, 319.5, 239.5, 640, 480)


def test_back_projection_divides_the_column_by_fx_and_the_row_by_fy():
    # x = (u - cx) z / fx, y = (v - cy) z / fy (pinhole model, OpenCV camera frame).
    depth = np.zeros((480, 640), dtype=np.float32)
    depth[339, 419] = 1.0
    cloud = backproject(depth, ANISOTROPIC, Pose(np.eye(4)))
    np.testing.assert_allclose(cloud.points, [[99.5 / 600.0, 99.5 / 500.0, 1.0]], atol=1e-9)
    assert cloud.points[0, 0] == pytest.approx(0.166, abs=1e-3)  # not 0.199: fx, not fy


def test_rescaling_a_camera_scales_fx_by_the_width_and_fy_by_the_height():
    half_wide = ANISOTROPIC.scaled(320, 120)  # x 1/2, y 1/4
    assert (half_wide.fx, half_wide.fy) == (300.0, 125.0)
    assert (half_wide.cx, half_wide.cy) == (159.5, 59.5)


@pytest.mark.parametrize("backend", ["fast", "reference"])
def test_both_renderers_project_x_with_fx_and_y_with_fy(backend):
    # A small Gaussian at camera (0.1, 0.2, 1) m lands at (cx + 0.1 fx, cy + 0.2 fy).
    k = Intrinsics(300.0, 200.0, 80.0, 60.0, 160, 120)
    one = GaussianSet(
        np.array([[0.1, 0.2, 1.0]]),
        np.eye(3)[None] * 0.003**2,
        np.array([[1.0, 1.0, 1.0]]),
        np.array([0.8]),
        np.ones(1),
    )
    alpha = render(one, Pose(np.eye(4)), k, return_alpha=True, backend=backend).alpha
    assert alpha is not None
    row, col = np.unravel_index(int(np.argmax(alpha)), alpha.shape)
    assert (col, row) == (80 + 30, 60 + 40)


def test_spl_is_success_times_shortest_over_the_longer_of_path_and_shortest():
    # SPL = S * l / max(p, l) (Anderson et al. 2018): at most 1, even when the agent's path
    # is shorter than the grid's shortest-path estimate l.
    from glmap_tools.sim.agents import OracleAgent, run_episodes
    from glmap_tools.sim.env import ObjectNavEnv
    from glmap_tools.sim.episodes import generate_episodes
    from glmap_tools.sim.render import CameraSpec
    from glmap_tools.worlds.generator import generate_apartment

    layout = generate_apartment(5, n_rooms=3)
    episodes = generate_episodes(layout, "objectnav", 1, seed=1)

    def oracle(shortest: float | None = None):  # type: ignore[no-untyped-def]
        chosen = episodes
        if shortest is not None:
            episode = dataclasses.replace(episodes.episodes[0], geodesic_distance=shortest)
            chosen = dataclasses.replace(episodes, episodes=[episode])
        env = ObjectNavEnv(layout=layout, episodes=chosen, camera=CameraSpec(32, 24))
        try:
            [result] = run_episodes(env, OracleAgent)
        finally:
            env.close()
        return result

    first = oracle()
    assert first.success and first.path_length > 0
    p = first.path_length
    longer, shorter = oracle(2.0 * p), oracle(0.5 * p)  # l = 2p: the path beat the estimate
    assert longer.path_length == shorter.path_length == p
    assert longer.spl == pytest.approx(1.0)  # l / p would give 2
    assert shorter.spl == pytest.approx(0.5)  # p / l would give 2


SOFA_TEXT = ("sofa", "a grey fabric sofa with soft cushions")
GREY = (0.5, 0.5, 0.55)
SOFA = [
    scenes.Box((-1.0, 0.0, 0.0), (1.0, 0.9, 0.45), GREY, 1),  # seat
    scenes.Box((-1.0, 0.7, 0.45), (1.0, 0.9, 0.9), GREY, 1),  # back
]
CUSHION = [scenes.Box((-0.2, 0.45, 0.47), (0.2, 0.68, 0.85), (0.85, 0.15, 0.1), 2)]


def test_an_observation_joins_an_instance_only_when_boxes_touch_and_gaussians_are_consistent():
    # Paper §3.1: semantic consistency, *then* geometric consistency (mergeable Gaussians).
    # A cushion leaning on the sofa's back lies inside the sofa's box, but none of its
    # Gaussians agrees with the sofa's. Described exactly like the sofa, so only geometry
    # decides, it must stay a separate instance (with "boxes touch OR consistent" it
    # swallowed the sofa).
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    frame, ids = scenes.view(scenes.floor() + SOFA, (0.3, -3.0, 1.4), (0.0, 0.3, 0.4))
    glmap.integrate(frame, scenes.semantics(ids, {1: SOFA_TEXT}))
    frame, ids = scenes.view(scenes.floor() + SOFA + CUSHION, (-0.3, -2.8, 1.3), (0.0, 0.3, 0.5))
    report = glmap.integrate(frame, scenes.semantics(ids, {2: SOFA_TEXT}))
    assert len(glmap.instances) == 2, report.instances_merged
    assert [c.global_id for c in report.instances_added] == [2]
    sofa, cushion = glmap.instances[1], glmap.instances[2]
    assert sofa.observations == 1 and cushion.observations == 1
    (lo, hi), (clo, chi) = sofa.gaussians.bounds(), cushion.gaussians.bounds()
    assert np.all(clo >= lo - 0.05) and np.all(chi <= hi + 0.05)  # the boxes do touch
