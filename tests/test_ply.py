"""Standard 3DGS PLY files: the layout viewers expect, round trips, tolerant reading."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.gaussians.ply import (
    SH_C0,
    property_names,
    quaternions_from_rotations,
    read_ply,
    rotations_from_quaternions,
    write_ply,
)
from glmap_tools.gaussians.types import GaussianSet

VIEWER_PROPERTIES = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity"]
VIEWER_PROPERTIES += ["scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def random_gaussians(n: int = 200, seed: int = 0) -> GaussianSet:
    """Random Gaussians incl. isotropic and flat ones, opacity 1 and 0.8 first."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    q *= np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    sigma = rng.uniform(0.005, 0.3, (n, 3))
    covs = np.einsum("nij,nj,nkj->nik", q, sigma**2, q) + 1e-6 * np.eye(3)
    covs[: min(n, 5)] = np.eye(3) * 1e-6  # isotropic: eigenvectors are arbitrary
    covs[min(n, 5) :][:1] = np.diag([1e-6, 0.01, 0.01])  # flat, as on a wall
    return GaussianSet(
        rng.uniform(-5, 5, (n, 3)),
        covs,
        rng.uniform(0, 1, (n, 3)),
        np.concatenate([[1.0, 0.8], rng.uniform(0.01, 1.0, n - 2)]),
        rng.integers(1, 500, n),
    )


def header_lines(path: Path) -> list[str]:
    data = path.read_bytes()
    return data[: data.index(b"end_header")].decode("ascii").splitlines()


def test_a_written_file_has_the_header_viewers_expect(tmp_path):
    g = random_gaussians(17)
    path = write_ply(tmp_path / "map.ply", g)
    lines = header_lines(path)
    assert lines[:3] == ["ply", "format binary_little_endian 1.0", "element vertex 17"]
    assert lines[3:] == [f"property float {name}" for name in VIEWER_PROPERTIES]
    size = os.path.getsize(path)
    body = size - (len(b"\n".join(line.encode() for line in lines)) + len(b"\nend_header\n"))
    assert body == 17 * len(VIEWER_PROPERTIES) * 4


def test_the_inria_degree_3_layout_adds_45_zero_sh_bands_before_opacity(tmp_path):
    g = random_gaussians(4)
    path = write_ply(tmp_path / "map.ply", g, sh_degree=3)
    names = [line.split()[-1] for line in header_lines(path)[3:]]
    assert names == property_names(3)
    assert names[9:54] == [f"f_rest_{i}" for i in range(45)]
    assert names[54] == "opacity"
    back = read_ply(path)
    np.testing.assert_allclose(back.colors, g.colors, atol=1e-6)


def test_a_round_trip_keeps_means_colours_opacities_and_covariances(tmp_path):
    g = random_gaussians()
    back = read_ply(write_ply(tmp_path / "map.ply", g))
    np.testing.assert_array_equal(back.means, g.means)
    np.testing.assert_allclose(back.colors, g.colors, atol=1e-6)
    np.testing.assert_allclose(back.opacities, g.opacities, atol=2e-6)
    scale = np.abs(g.covs).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(back.covs / scale, g.covs / scale, atol=2e-6)
    np.testing.assert_array_equal(back.counts, 1)  # counts are not part of the format


def test_stored_values_follow_the_3dgs_conventions(tmp_path):
    g = random_gaussians(8)
    path = write_ply(tmp_path / "map.ply", g)
    data = path.read_bytes()
    body = data[data.index(b"end_header\n") + len(b"end_header\n") :]
    v = np.frombuffer(body, dtype=[(name, "<f4") for name in VIEWER_PROPERTIES])
    np.testing.assert_allclose(v["f_dc_0"], (g.colors[:, 0] - 0.5) / SH_C0, rtol=1e-6)
    np.testing.assert_allclose(1 / (1 + np.exp(-v["opacity"][1:])), g.opacities[1:], atol=1e-6)
    quats = np.stack([v[f"rot_{i}"] for i in range(4)], axis=1)
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-6)
    rot = rotations_from_quaternions(quats)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-5)
    variances = np.exp(2 * np.stack([v[f"scale_{i}"] for i in range(3)], axis=1))
    np.testing.assert_allclose(np.sort(variances), np.linalg.eigvalsh(g.covs), rtol=1e-5)
    assert not (v["nx"].any() or v["ny"].any() or v["nz"].any())


def test_quaternions_and_rotations_convert_both_ways():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(500, 4))
    q[:4] = np.eye(4)  # each component dominant once, incl. 180 degree turns
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.sign(q[:, :1] + (q[:, :1] == 0))
    back = quaternions_from_rotations(rotations_from_quaternions(q))
    np.testing.assert_allclose(back, q, atol=1e-12)


def test_reading_tolerates_other_orders_extra_properties_doubles_and_raw_quaternions(tmp_path):
    g = random_gaussians(30)
    canonical = read_ply(write_ply(tmp_path / "a.ply", g))
    names = VIEWER_PROPERTIES[::-1] + ["f_rest_0", "f_rest_1"]
    data = (tmp_path / "a.ply").read_bytes()
    body = data[data.index(b"end_header\n") + len(b"end_header\n") :]
    v = np.frombuffer(body, dtype=[(name, "<f4") for name in VIEWER_PROPERTIES])
    out = np.zeros(len(v), dtype=[(name, "<f8") for name in names])
    for name in VIEWER_PROPERTIES:
        out[name] = v[name]
    for i in range(4):
        out[f"rot_{i}"] *= 3.0  # viewers store unnormalised quaternions
    header = ["ply", "format binary_little_endian 1.0", "comment from elsewhere"]
    header += ["element camera 1", "property float fov"]
    header += [f"element vertex {len(v)}"] + [f"property double {n}" for n in names]
    path = tmp_path / "b.ply"
    path.write_bytes(
        ("\n".join([*header, "end_header"]) + "\n").encode()
        + np.float32(1.0).tobytes()
        + out.tobytes()
    )
    back = read_ply(path)
    for field in ("means", "colors", "opacities"):
        np.testing.assert_allclose(getattr(back, field), getattr(canonical, field), atol=1e-6)
    np.testing.assert_allclose(back.covs, canonical.covs, atol=1e-8)


def test_an_ascii_file_reads_like_the_binary_one(tmp_path):
    g = random_gaussians(5)
    binary = read_ply(write_ply(tmp_path / "a.ply", g))
    data = (tmp_path / "a.ply").read_bytes()
    body = data[data.index(b"end_header\n") + len(b"end_header\n") :]
    v = np.frombuffer(body, dtype=[(name, "<f4") for name in VIEWER_PROPERTIES])
    rows = "\n".join(" ".join(repr(float(x)) for x in row) for row in v.tolist())
    header = data[: data.index(b"end_header")].decode().replace("binary_little_endian", "ascii")
    (tmp_path / "b.ply").write_text(header + "end_header\n" + rows + "\n")
    ascii_read = read_ply(tmp_path / "b.ply")
    np.testing.assert_allclose(ascii_read.covs, binary.covs, atol=1e-9)
    np.testing.assert_allclose(ascii_read.colors, binary.colors, atol=1e-7)


def test_an_empty_set_round_trips(tmp_path):
    back = read_ply(write_ply(tmp_path / "empty.ply", GaussianSet.empty()))
    assert len(back) == 0


def test_a_failed_write_leaves_no_partial_file_and_keeps_the_old_one(tmp_path, monkeypatch):
    path = write_ply(tmp_path / "map.ply", random_gaussians(3))
    before = path.read_bytes()

    def fail(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(StoreError, match="disk full"):
        write_ply(path, random_gaussians(50))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.ply"]


def test_writing_into_a_missing_folder_or_a_non_set_is_rejected(tmp_path):
    with pytest.raises(StoreError, match="does not exist"):
        write_ply(tmp_path / "nowhere" / "map.ply", random_gaussians(3))
    with pytest.raises(InvalidInputError, match="GaussianSet"):
        write_ply(tmp_path / "map.ply", np.zeros((3, 3)))  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="sh_degree=2"):
        write_ply(tmp_path / "map.ply", random_gaussians(3), sh_degree=2)


def test_unreadable_files_raise_store_errors_that_say_why(tmp_path):
    with pytest.raises(StoreError, match="cannot read"):
        read_ply(tmp_path / "missing.ply")
    (tmp_path / "junk.ply").write_bytes(b"hello")
    with pytest.raises(StoreError, match="not a PLY"):
        read_ply(tmp_path / "junk.ply")
    path = write_ply(tmp_path / "map.ply", random_gaussians(10))
    (tmp_path / "cut.ply").write_bytes(path.read_bytes()[:-7])
    with pytest.raises(StoreError, match="truncated"):
        read_ply(tmp_path / "cut.ply")
    points = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
    (tmp_path / "points.ply").write_bytes((points + "end_header\n").encode() + bytes(4))
    with pytest.raises(StoreError, match="lacks the 3DGS properties"):
        read_ply(tmp_path / "points.ply")


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("y", np.nan),
        ("f_dc_1", np.inf),
        ("scale_0", 400.0),
        ("scale_1", 50.0),  # exp(100) is finite in float64, not in the float32 a set holds
        ("rot_2", np.nan),
        ("opacity", np.nan),
    ],
)
def test_a_vertex_that_is_not_finite_is_refused_by_its_index(tmp_path, name, value):
    path = write_ply(tmp_path / "map.ply", random_gaussians(6))
    data = path.read_bytes()
    start = data.index(b"end_header\n") + len(b"end_header\n")
    v = np.frombuffer(data[start:], dtype=[(p, "<f4") for p in VIEWER_PROPERTIES]).copy()
    v[name][4] = value
    path.write_bytes(data[:start] + v.tobytes())
    with pytest.raises(StoreError, match=r"vertex 4 of 6 has a NaN or infinite .* \(1 such"):
        read_ply(path)


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (("element vertex 10", "element vertex 1e3"), "gives no count of 'vertex'"),
        (("element vertex 10", "element vertex -5"), "gives no count of 'vertex'"),
        (("property float y", "property float x"), "property 'x' of element 'vertex' is declared"),
        (("property float y", "property"), "cannot read header line 'property'"),
        (("end_header\n", "end_header"), "'end_header' line does not end"),
    ],
)
def test_a_malformed_header_is_refused_naming_the_line(tmp_path, edit, said):
    path = write_ply(tmp_path / "map.ply", random_gaussians(10))
    data = path.read_bytes()
    start = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:start].decode().replace(*edit)
    body = b"" if edit[1] == "end_header" else data[start:]
    path.write_bytes(header.encode() + body)
    with pytest.raises(StoreError, match=re.escape(said)):
        read_ply(path)


def test_a_zero_or_tiny_quaternion_reads_as_no_rotation(tmp_path):
    path = write_ply(tmp_path / "map.ply", random_gaussians(6))
    data = path.read_bytes()
    start = data.index(b"end_header\n") + len(b"end_header\n")
    v = np.frombuffer(data[start:], dtype=[(p, "<f4") for p in VIEWER_PROPERTIES]).copy()
    for k, q in ((2, 0.0), (3, 1e-12)):
        for i in range(4):
            v[f"rot_{i}"][k] = q
    path.write_bytes(data[:start] + v.tobytes())
    g = read_ply(path)
    for k in (2, 3):
        variances = np.exp(2.0 * np.array([v[f"scale_{i}"][k] for i in range(3)], dtype=float))
        np.testing.assert_allclose(g.covs[k], np.diag(variances), rtol=1e-5)
