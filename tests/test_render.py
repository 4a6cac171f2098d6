"""The splatting rasterizer: fast == reference, analytic cases, culling and input limits.

Tolerances (fast vs reference, per pixel): rgb and alpha max abs 2e-3; depth max abs 2e-3 m
where alpha >= 1e-3. Both backends compute in float64 with the same contract, so in
practice they agree to float32 rounding.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians import _render_bins, _render_numba
from glmap_tools.gaussians.render import (
    LOW_PASS,
    MAX_RENDER_PIXELS,
    MAX_RENDER_SIDE,
    RenderResult,
    render,
    render_image,
)
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose

RGB_TOL = 2e-3
ALPHA_TOL = 2e-3
DEPTH_TOL = 2e-3  # metres, where alpha >= 1e-3


def make_set(means, covs, colors, opacities) -> GaussianSet:
    n = len(means)
    return GaussianSet(
        np.asarray(means), np.asarray(covs), np.asarray(colors), np.asarray(opacities), np.ones(n)
    )


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    q *= np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    q[np.linalg.det(q) < 0, :, 0] *= -1
    return q


def random_blobs(seed: int, n: int = 150) -> GaussianSet:
    """Blobs of 2-25 cm around (0, 0, 1.5) in a z-up world, seen by the cameras below."""
    rng = np.random.default_rng(seed)
    means = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 2.5], (n, 3))
    rot = random_rotations(rng, n)
    sigma = rng.uniform(0.02, 0.25, (n, 3))
    covs = np.einsum("nij,nj,nkj->nik", rot, sigma**2, rot) + 1e-6 * np.eye(3)
    return make_set(means, covs, rng.uniform(0, 1, (n, 3)), rng.uniform(0.05, 1.0, n))


def textured_wall() -> GaussianSet:
    """A 2 m x 1.5 m wall at x = 2 of flat 4 cm Gaussians in a checker of two colours."""
    ys, zs = np.meshgrid(np.arange(-1.0, 1.0, 0.05), np.arange(0.5, 2.0, 0.05))
    ys, zs = ys.ravel(), zs.ravel()
    n = len(ys)
    means = np.stack([np.full(n, 2.0), ys, zs], axis=1)
    covs = np.tile(np.diag([1e-6, 0.03**2, 0.03**2]), (n, 1, 1))
    checker = ((np.floor(ys / 0.2) + np.floor(zs / 0.2)) % 2).astype(bool)
    colors = np.where(checker[:, None], [0.9, 0.8, 0.1], [0.1, 0.2, 0.7])
    return make_set(means, covs, colors, np.full(n, 0.9))


def elongated_ellipsoids() -> GaussianSet:
    """Long thin slanted needles (1 m x 5 mm), which take the rasterizer's thin-footprint path."""
    rng = np.random.default_rng(7)
    n = 12
    means = rng.uniform([1.5, -0.8, 0.8], [3.0, 0.8, 2.2], (n, 3))
    rot = random_rotations(rng, n)
    sigma = np.tile([0.5, 0.005, 0.005], (n, 1))
    covs = np.einsum("nij,nj,nkj->nik", rot, sigma**2, rot) + 1e-6 * np.eye(3)
    return make_set(means, covs, rng.uniform(0, 1, (n, 3)), rng.uniform(0.3, 1.0, n))


CAMERA = Pose.looking_at(np.array([-2.0, 0.3, 1.6]), np.array([0.0, 0.0, 1.5]))
OBLIQUE = Pose.looking_at(np.array([0.5, -1.5, 1.2]), np.array([2.0, 0.2, 1.3]))
INSIDE = Pose.looking_at(np.array([0.0, 0.0, 1.5]), np.array([1.0, 0.2, 1.4]))  # amid blobs


def assert_backends_agree(
    g: GaussianSet, pose: Pose, k: Intrinsics, near: float = 0.05, far: float = 50.0
) -> RenderResult:
    kw = dict(near=near, far=far, return_depth=True, return_alpha=True, background=(0.2, 0.5, 1))
    fast = render(g, pose, k, backend="fast", **kw)
    ref = render(g, pose, k, backend="reference", **kw)
    assert fast.rgb.shape == (k.height, k.width, 3) and fast.rgb.dtype == np.float32
    assert np.abs(fast.rgb - ref.rgb).max() <= RGB_TOL
    assert np.abs(fast.alpha - ref.alpha).max() <= ALPHA_TOL
    seen = ref.alpha >= 1e-3
    assert np.abs(fast.depth - ref.depth)[seen].max(initial=0.0) <= DEPTH_TOL
    return ref


@pytest.mark.parametrize("size", [(64, 48), (97, 61)])
@pytest.mark.parametrize("seed", [0, 1])
def test_fast_matches_reference_on_random_blobs(size, seed):
    ref = assert_backends_agree(random_blobs(seed), CAMERA, Intrinsics.from_fov(*size, 80))
    assert 0.3 < ref.alpha.mean() < 0.999  # the scene covers the view, not trivially


@pytest.mark.parametrize("pose", [CAMERA, OBLIQUE], ids=["frontal", "oblique"])
def test_fast_matches_reference_on_a_textured_wall(pose):
    ref = assert_backends_agree(textured_wall(), pose, Intrinsics.from_fov(97, 61, 70))
    assert ref.alpha.max() > 0.99


def test_fast_matches_reference_on_elongated_ellipsoids():
    g = elongated_ellipsoids()
    k = Intrinsics.from_fov(97, 61, 80)
    ref = assert_backends_agree(g, CAMERA, k)
    assert ref.alpha.max() > 0.2
    # The needles exercise the rasterizer's thin-footprint path as well as the compact one.
    params, _, valid = _project_fast(g, CAMERA, k)
    compact = params[valid, _render_numba.OPACITY] > 0.0
    assert compact.any() and not compact.all()


def _project_fast(g: GaussianSet, pose: Pose, k: Intrinsics):
    from glmap_tools.gaussians._render_common import ALPHA_MIN, SIGMA_EXTENT, camera_setup

    cam = camera_setup(pose, k)
    n = len(g)
    params = np.empty((n, _render_numba.N_PARAMS), np.float32)
    spans = np.empty((n, _render_numba.N_SPAN), np.float32)
    depth = np.empty(n)
    rects = np.empty((n, 4), np.int16)
    tiles = np.empty((n, 4), np.int16)
    valid = np.empty(n, np.bool_)
    camera = np.array([k.fx, k.fy, k.cx, k.cy, *cam.tan_lo, *cam.tan_hi])
    _render_numba.project_kernel(
        g.means, g.covs, g.colors, g.opacities, cam.rotation, cam.translation, camera,
        k.width, k.height, 0.05, 50.0, LOW_PASS, ALPHA_MIN, SIGMA_EXTENT, 16, 16,
        params, spans, depth, rects, tiles, valid,
    )  # fmt: skip
    return params, rects, valid


def test_fast_matches_reference_with_gaussians_behind_the_camera_and_past_far():
    g = GaussianSet.concat([random_blobs(2), random_blobs(3)])
    k = Intrinsics.from_fov(64, 48, 90)
    _, _, valid = _project_fast(g, INSIDE, k)
    assert 0 < valid.sum() < len(g)  # some are culled: behind, or out of view
    assert_backends_agree(g, INSIDE, k)
    assert_backends_agree(g, CAMERA, k, near=2.0, far=2.6)  # a slab in the middle


def test_fast_result_does_not_depend_on_the_tile_shape():
    g = GaussianSet.concat([random_blobs(4), elongated_ellipsoids()])
    k = Intrinsics.from_fov(97, 61, 80)
    base = _render_numba.render_fast(g, CAMERA, k, (1.0, 1.0, 1.0), 0.05, 50.0, (16, 16))
    for tile in [(8, 32), (64, 8), (5, 7)]:
        other = _render_numba.render_fast(g, CAMERA, k, (1.0, 1.0, 1.0), 0.05, 50.0, tile)
        for a, b in zip(base, other, strict=True):
            np.testing.assert_allclose(a, b, atol=1e-6)


@pytest.mark.parametrize("backend", ["fast", "reference"])
def test_an_isotropic_gaussian_peaks_at_its_projection_with_the_ewa_footprint(backend):
    sigma, z, opacity = 0.05, 2.0, 0.7
    k = Intrinsics(200.0, 200.0, 40.0, 30.0, 81, 61)
    g = make_set([[0.0, 0.0, z]], [np.eye(3) * sigma**2], [[1.0, 0.0, 0.0]], [opacity])
    res = render(g, Pose.identity(), k, return_alpha=True, return_depth=True, backend=backend)
    peak = np.unravel_index(np.argmax(res.alpha), res.alpha.shape)
    assert peak == (30, 40)
    assert res.alpha[30, 40] == pytest.approx(opacity, abs=1e-6)
    np.testing.assert_allclose(res.depth[res.alpha > 0], z, atol=1e-6)
    # Half-maximum radius along the row through the centre: the screen std is
    # sqrt((f sigma / z)^2 + LOW_PASS), the alpha halves at sqrt(2 ln 2) of it.
    expected = math.sqrt(2 * math.log(2)) * math.sqrt((200.0 * sigma / z) ** 2 + LOW_PASS)
    row = res.alpha[30, 40:].astype(np.float64)
    i = int(np.argmax(row < opacity / 2))
    half_max = i - 1 + (row[i - 1] - opacity / 2) / (row[i - 1] - row[i])  # linear crossing
    assert half_max == pytest.approx(expected, abs=0.1)
    np.testing.assert_allclose(res.alpha[30, 40::-1], res.alpha[30, 40:], atol=1e-6)  # symmetric


def test_a_front_gaussian_hides_one_behind_whatever_their_order_in_the_set():
    k = Intrinsics(100.0, 100.0, 10.0, 10.0, 21, 21)
    big = np.eye(3) * 0.2**2
    g = make_set([[0, 0, 3.0], [0, 0, 2.0]], [big, big], [[0, 0, 1.0], [1.0, 0, 0]], [0.9, 1.0])
    rgb = render(g, Pose.identity(), k, background=(0, 1, 0)).rgb[10, 10]
    # Red in front takes alpha 0.99 (the cap); blue behind gets 0.9 of the remaining 0.01.
    np.testing.assert_allclose(rgb, [0.99, 0.001, 0.009], atol=1e-6)


@pytest.mark.parametrize("backend", ["fast", "reference"])
def test_a_pixel_stops_compositing_before_its_transmittance_drops_below_1e_4(backend):
    k = Intrinsics(100.0, 100.0, 10.0, 10.0, 21, 21)
    n = 30
    means = np.stack([np.zeros(n), np.zeros(n), np.linspace(2.0, 3.0, n)], axis=1)
    colors = np.tile([0.0, 0.0, 1.0], (n, 1))
    colors[0] = [1.0, 0.0, 0.0]
    g = make_set(means, np.tile(np.eye(3) * 0.2**2, (n, 1, 1)), colors, np.full(n, 0.5))
    res = render(g, Pose.identity(), k, return_alpha=True, backend=backend)
    # 13 layers of alpha 0.5 leave T = 2^-13 > 1e-4; the 14th would drop it below.
    assert 1.0 - res.alpha[10, 10] == pytest.approx(2.0**-13, rel=1e-5)
    t = 2.0**-13  # what shows of the white background
    np.testing.assert_allclose(res.rgb[10, 10], [0.5 + t, t, 0.5 - t + t], atol=1e-6)


def test_an_empty_set_renders_the_background():
    k = Intrinsics.from_fov(33, 17, 60)
    res = render(GaussianSet.empty(), CAMERA, k, background=(0.1, 0.2, 0.3), return_depth=True)
    np.testing.assert_array_equal(
        res.rgb, np.broadcast_to(np.float32([0.1, 0.2, 0.3]), res.rgb.shape)
    )
    assert not res.depth.any()


@pytest.mark.parametrize("backend", ["fast", "reference"])
def test_gaussians_behind_the_camera_or_past_far_contribute_nothing(backend):
    k = Intrinsics.from_fov(40, 30, 90)
    front = random_blobs(5, n=40)
    behind = front.subset(np.arange(40))
    behind = make_set(behind.means * [1, 1, -1], behind.covs, behind.colors, behind.opacities)
    far = make_set(front.means + [0, 0, 25], front.covs, front.colors, front.opacities)
    front = make_set(front.means - [0, 0, 1.5] + [0, 0, 3], front.covs, front.colors, [1.0] * 40)
    alone = render(front, Pose.identity(), k, backend=backend, far=20.0)
    both = render(
        GaussianSet.concat([behind, front, far]), Pose.identity(), k, backend=backend, far=20.0
    )
    assert alone.rgb.min() < 0.9
    np.testing.assert_array_equal(alone.rgb, both.rgb)
    only_hidden = render(GaussianSet.concat([behind, far]), Pose.identity(), k, far=20.0)
    assert (only_hidden.rgb == 1.0).all()


def test_non_finite_gaussians_are_skipped():
    k = Intrinsics.from_fov(40, 30, 80)
    g = random_blobs(6, n=30)
    bad = make_set(np.full((2, 3), np.nan), g.covs[:2], g.colors[:2], g.opacities[:2])
    assert_backends_agree(GaussianSet.concat([g, bad]), CAMERA, k)
    np.testing.assert_array_equal(
        render(GaussianSet.concat([g, bad]), CAMERA, k).rgb, render(g, CAMERA, k).rgb
    )


def test_render_image_is_uint8_rgb_and_optional_outputs_are_none_unless_asked():
    k = Intrinsics.from_fov(32, 24, 80)
    img = render_image(random_blobs(0, n=20), CAMERA, k)
    assert img.dtype == np.uint8 and img.shape == (24, 32, 3)
    res = render(random_blobs(0, n=20), CAMERA, k)
    assert res.depth is None and res.alpha is None
    np.testing.assert_array_equal(res.to_uint8(), img)


def test_an_image_over_the_side_cap_is_rejected_naming_the_value_and_cap():
    k = Intrinsics(500.0, 500.0, 10.0, 10.0, MAX_RENDER_SIDE + 1, 10)
    with pytest.raises(InvalidInputError, match=rf"{MAX_RENDER_SIDE + 1}.*{MAX_RENDER_SIDE}"):
        render(GaussianSet.empty(), CAMERA, k)


def test_an_image_over_the_pixel_cap_is_rejected_naming_the_value_and_cap():
    k = Intrinsics(500.0, 500.0, 10.0, 10.0, MAX_RENDER_SIDE, MAX_RENDER_SIDE)
    with pytest.raises(InvalidInputError, match=rf"{MAX_RENDER_SIDE**2}.*{MAX_RENDER_PIXELS}"):
        render(GaussianSet.empty(), CAMERA, k)


def test_a_zero_size_image_or_a_non_rigid_pose_never_reaches_the_renderer():
    with pytest.raises(InvalidInputError, match="width=0"):
        Intrinsics(500.0, 500.0, 10.0, 10.0, 0, 10)
    with pytest.raises(InvalidInputError, match="not rigid"):
        Pose(np.diag([2.0, 1.0, 1.0, 1.0]))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"near": 0.0}, "near=0.0"),
        ({"near": 3.0, "far": 2.0}, "far=2.0"),
        ({"far": math.inf}, "far=inf"),
        ({"background": (1.0, 2.0, 0.0)}, "background"),
        ({"background": (1.0, 1.0)}, "background"),
        ({"backend": "refrence"}, "Did you mean 'reference'"),
        ({"background": "white"}, "background='white' must be three RGB floats"),
        ({"background": {}}, "background={} must be three RGB floats"),
        ({"backend": ["fast"]}, r"backend=\['fast'\] is not one of"),
        ({"return_depth": "yes"}, "return_depth='yes' must be True or False"),
        ({"return_alpha": np.ones(3)}, "return_alpha=array"),
    ],
)
def test_bad_render_arguments_are_rejected_with_a_fix(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        render(random_blobs(0, n=3), CAMERA, Intrinsics.from_fov(8, 8, 60), **kwargs)


def test_a_raw_matrix_instead_of_a_pose_is_rejected_with_a_fix():
    with pytest.raises(InvalidInputError, match="Pose"):
        render(random_blobs(0, n=3), np.eye(4), Intrinsics.from_fov(8, 8, 60))  # type: ignore[arg-type]


@pytest.mark.parametrize("n", [0, 1, 7, 5000])
def test_the_radix_depth_order_equals_a_stable_argsort_with_ties_in_input_order(n):
    rng = np.random.default_rng(n)
    depth = rng.uniform(0.05, 50.0, n)
    depth[::3] = np.round(depth[::3])  # many exact ties
    valid = rng.uniform(size=n) < 0.8
    depth[~valid] = np.nan  # culled entries hold garbage
    kept = np.flatnonzero(valid)
    expected = kept[np.argsort(depth[kept], kind="stable")]
    np.testing.assert_array_equal(_render_bins.depth_order_kernel(valid, depth), expected)


def test_renders_from_several_threads_at_once_equal_sequential_ones():
    from concurrent.futures import ThreadPoolExecutor

    k = Intrinsics.from_fov(48, 32, 80)
    scenes = [random_blobs(seed, n=60) for seed in range(4)]
    sequential = [render(g, CAMERA, k).rgb for g in scenes]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda g: render(g, CAMERA, k).rgb, scenes))
    for a, b in zip(sequential, threaded, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_scattered_tile_order_visits_every_tile_once():
    for n in [1, 2, 3, 12, 300, 1200, 4096]:
        stride = _render_numba.scatter_stride(n)
        assert sorted((np.arange(n) * stride) % n) == list(range(n))
