"""Read and write Gaussians in the standard 3D Gaussian Splatting PLY layout.

The file is what 3DGS viewers (SuperSplat, the INRIA SIBR viewer, gsplat tools) open: a
binary little-endian `vertex` element with float properties, in this order:

    x y z  nx ny nz  f_dc_0 f_dc_1 f_dc_2  [f_rest_0 .. f_rest_44]  opacity
    scale_0 scale_1 scale_2  rot_0 rot_1 rot_2 rot_3

- f_dc_k = (c_k - 0.5) / C0 with C0 = 0.28209479177387814 (the degree-0 SH basis);
  f_rest_* (higher SH bands) are written as zeros only when asked for (`sh_degree=3`).
- opacity is the logit of the opacity; scale_k the log of the standard deviations along the
  covariance eigenvectors (sqrt of its eigenvalues); rot the unit quaternion (w, x, y, z)
  of the eigenvector rotation (det +1). Normals are zeros.
- Point counts are not part of the layout: reading sets every count to 1.

Reading is tolerant: any property order, extra properties (f_rest_*, normals, ...), other
elements, float or double or integer types, either endianness or ascii; colours come from
f_dc_* or, failing that, red/green/blue; quaternions are normalised.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from glmap_tools.atomic import write_atomic
from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry.rotations import rotations_from_quaternions

SH_C0 = 0.28209479177387814
OPACITY_CLIP = 1e-6  # opacities are clipped to [eps, 1 - eps] so their logit is finite
MIN_VARIANCE = 1e-20  # m^2; eigenvalues are clipped here before the log
SH_REST_COUNT = {0: 0, 3: 45}  # f_rest_* properties per SH degree

_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_REQUIRED = ["x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2"]
_REQUIRED += ["rot_0", "rot_1", "rot_2", "rot_3"]


def property_names(sh_degree: int = 0) -> list[str]:
    """The vertex property names `write_ply` writes, in file order."""
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(SH_REST_COUNT[sh_degree])]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    return names


def quaternions_from_rotations(rot: np.ndarray) -> np.ndarray:
    """[N, 4] unit quaternions (w, x, y, z), w >= 0, of [N, 3, 3] rotation matrices."""
    r = np.asarray(rot, dtype=np.float64)
    # Shepperd's method: start from the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2.
    trace = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    diag = np.stack([trace, r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    k = np.argmax(diag, axis=1)
    q = np.empty((len(r), 4))
    s = np.sqrt(np.maximum(1.0 + 2.0 * diag[np.arange(len(r)), k] - trace, 1e-300))
    for case in range(4):
        sel = k == case
        if not sel.any():
            continue
        m, ss = r[sel], s[sel]
        d21, d02, d10 = m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]
        s21, s02, s10 = m[:, 2, 1] + m[:, 1, 2], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 0] + m[:, 0, 1]
        if case == 0:
            q[sel] = np.stack([ss / 2, d21 / (2 * ss), d02 / (2 * ss), d10 / (2 * ss)], 1)
        elif case == 1:
            q[sel] = np.stack([d21 / (2 * ss), ss / 2, s10 / (2 * ss), s02 / (2 * ss)], 1)
        elif case == 2:
            q[sel] = np.stack([d02 / (2 * ss), s10 / (2 * ss), ss / 2, s21 / (2 * ss)], 1)
        else:
            q[sel] = np.stack([d10 / (2 * ss), s02 / (2 * ss), s21 / (2 * ss), ss / 2], 1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(q[:, :1] < 0, -q, q)


def _vertex_records(gaussians: GaussianSet, sh_degree: int) -> np.ndarray:
    """The structured [N] vertex array of `gaussians` in the standard layout."""
    names = property_names(sh_degree)
    records = np.zeros(len(gaussians), dtype=[(name, "<f4") for name in names])
    covs = gaussians.covs.astype(np.float64)
    eigenvalues, eigenvectors = np.linalg.eigh(0.5 * (covs + covs.transpose(0, 2, 1)))
    flip = np.linalg.det(eigenvectors) < 0
    eigenvectors[flip, :, 2] *= -1.0  # a proper rotation (det +1)
    log_scales = 0.5 * np.log(np.maximum(eigenvalues, MIN_VARIANCE))
    quats = quaternions_from_rotations(eigenvectors)
    op = np.clip(gaussians.opacities.astype(np.float64), OPACITY_CLIP, 1.0 - OPACITY_CLIP)
    for i, axis in enumerate("xyz"):
        records[axis] = gaussians.means[:, i]
        records[f"f_dc_{i}"] = (gaussians.colors[:, i].astype(np.float64) - 0.5) / SH_C0
        records[f"scale_{i}"] = log_scales[:, i]
    records["opacity"] = np.log(op / (1.0 - op))
    for i in range(4):
        records[f"rot_{i}"] = quats[:, i]
    return records


def write_ply(path: str | os.PathLike[str], gaussians: GaussianSet, *, sh_degree: int = 0) -> Path:
    """Write `gaussians` as a standard 3DGS PLY file, atomically (temp file + rename).

    Args:
        path: destination file; its folder must exist. An existing file is replaced only
            once the new one is completely written.
        gaussians: the Gaussians (counts are not stored).
        sh_degree: 0 writes only the SH DC colour; 3 adds the 45 f_rest_* properties (zeros)
            of the INRIA layout, for viewers that expect degree-3 files.

    Returns:
        The path written.

    Raises:
        InvalidInputError: `gaussians` is not a GaussianSet or sh_degree is not 0 or 3.
        StoreError: the file cannot be written.
    """
    if not isinstance(gaussians, GaussianSet):
        raise InvalidInputError(
            f"gaussians is a {type(gaussians).__name__}; pass a glmap_tools.gaussians.GaussianSet."
        )
    if sh_degree not in SH_REST_COUNT:
        raise InvalidInputError(
            f"sh_degree={sh_degree!r} is not one of {sorted(SH_REST_COUNT)}; use 0 (colour only) "
            "or 3 (the INRIA layout with zero f_rest_* bands)."
        )
    records = _vertex_records(gaussians, sh_degree)
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(gaussians)}"]
    header += [f"property float {name}" for name in records.dtype.names or ()]
    header += ["end_header"]
    return write_atomic(path, [("\n".join(header) + "\n").encode("ascii"), records.tobytes()])


def _parse_header(data: bytes, path: Path) -> tuple[str, list[tuple[str, int, list]], int]:
    """(format, [(element, count, [(property, dtype str)])], byte offset of the body)."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise StoreError(f"{path} is not a PLY file (no 'ply' magic or 'end_header').")
    body = data.find(b"\n", end) + 1
    if body == 0:
        raise StoreError(f"{path} is truncated: its header's 'end_header' line does not end.")
    fmt = ""
    elements: list[tuple[str, int, list]] = []
    for raw in data[:end].decode("ascii", errors="replace").splitlines():
        words = raw.split()
        if not words or words[0] in ("ply", "comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3:
            if not words[2].isdigit():
                raise StoreError(
                    f"{path}: header line {raw!r} gives no count of {words[1]!r} elements; "
                    "a PLY element line is 'element NAME COUNT' with a whole number."
                )
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and len(words) >= 2:
            if words[1] == "list":
                raise StoreError(
                    f"{path}: list property {words[-1]!r} in element {elements[-1][0]!r} is not "
                    "supported; export the splats without list properties."
                )
            if len(words) != 3 or words[1] not in _PLY_TYPES:
                raise StoreError(f"{path}: cannot read header line {raw!r}.")
            if any(name == words[2] for name, _ in elements[-1][2]):
                raise StoreError(
                    f"{path}: property {words[2]!r} of element {elements[-1][0]!r} is declared "
                    "twice; a PLY element names each property once."
                )
            elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
        else:
            raise StoreError(f"{path}: cannot read header line {raw!r}.")
    if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
        raise StoreError(f"{path}: PLY format {fmt!r} is not binary or ascii.")
    return fmt, elements, body


def _read_vertices(path: Path) -> np.ndarray:
    """The structured array of the `vertex` element of a PLY file."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise StoreError(f"cannot read {path}: {exc}; check the path.") from exc
    fmt, elements, offset = _parse_header(data, path)
    if fmt == "ascii":
        lines = data[offset:].decode("ascii", errors="replace").splitlines()
        row = 0
        for name, count, props in elements:
            dtype = np.dtype([(p, "f8") for p, _ in props])
            if name == "vertex":
                try:
                    values = np.loadtxt(lines[row : row + count], ndmin=2)
                    return np.rec.fromarrays(values.T, dtype=dtype)
                except ValueError as exc:
                    raise StoreError(f"{path}: unreadable ascii vertex data: {exc}.") from exc
            row += count
    else:
        endian = "<" if fmt == "binary_little_endian" else ">"
        for name, count, props in elements:
            dtype = np.dtype([(p, endian + t) for p, t in props])
            if offset + count * dtype.itemsize > len(data):
                raise StoreError(
                    f"{path} is truncated: element {name!r} needs {count * dtype.itemsize} bytes "
                    f"at offset {offset}, the file has {len(data)}."
                )
            if name == "vertex":
                return np.frombuffer(data, dtype=dtype, count=count, offset=offset)
            offset += count * dtype.itemsize
    raise StoreError(f"{path} has no 'vertex' element; it holds no Gaussians.")


def read_ply(path: str | os.PathLike[str]) -> GaussianSet:
    """Read Gaussians from a 3DGS PLY file (see the module docstring for what is accepted).

    Covariances are R diag(exp(2 scale)) R^T; colours 0.5 + C0 f_dc clipped to [0, 1];
    opacities the sigmoid of the stored logit; counts 1.

    Raises:
        StoreError: the file is missing, truncated, has a header line it cannot read (a
            count that is not a whole number, a property declared twice) or lacks the
            Gaussian properties, or a vertex holds a value that is not finite in float32.
    """
    path = Path(path)
    v = _read_vertices(path)
    names = set(v.dtype.names or ())
    missing = [p for p in _REQUIRED if p not in names]
    has_dc = all(f"f_dc_{i}" in names for i in range(3))
    has_rgb = all(c in names for c in ("red", "green", "blue"))
    if missing or not (has_dc or has_rgb):
        missing += [] if has_dc or has_rgb else ["f_dc_0..2 (or red/green/blue)"]
        raise StoreError(
            f"{path} lacks the 3DGS properties {missing}; it is not a standard Gaussian "
            "splatting PLY (compressed or packed splat files must be decompressed first)."
        )

    def col(name: str) -> np.ndarray:
        with np.errstate(invalid="ignore"):  # a signalling NaN; refused below with the rest
            return np.asarray(v[name], dtype=np.float64)

    n = len(v)
    means = np.stack([col("x"), col("y"), col("z")], axis=1)
    if has_dc:
        colors = 0.5 + SH_C0 * np.stack([col(f"f_dc_{i}") for i in range(3)], axis=1)
    else:
        scale = 255.0 if np.dtype(v.dtype["red"]).kind in "iu" else 1.0
        colors = np.stack([col(c) / scale for c in ("red", "green", "blue")], axis=1)
    quats = np.stack([col(f"rot_{i}") for i in range(4)], axis=1)
    norms = np.linalg.norm(quats, axis=1)
    bad_rotation = ~np.isfinite(norms)  # refused below, with the other values
    # a zero quaternion means no rotation (and one too short to normalise)
    quats[bad_rotation | (norms <= 1e-9)] = (1.0, 0.0, 0.0, 0.0)
    rot = rotations_from_quaternions(quats)
    with np.errstate(over="ignore", invalid="ignore"):
        variances = np.exp(2.0 * np.stack([col(f"scale_{i}") for i in range(3)], axis=1))
        covs = np.einsum("nij,nj,nkj->nik", rot, variances, rot)
        opacities = 1.0 / (1.0 + np.exp(-col("opacity")))
        # finite in the float32 a GaussianSet holds (a scale of 50 is finite in float64 only)
        bad = bad_rotation | ~(
            np.isfinite(means.astype(np.float32)).all(axis=1)
            & np.isfinite(colors).all(axis=1)
            & np.isfinite(covs.astype(np.float32)).all(axis=(1, 2))
            & np.isfinite(opacities)
        )
    if bad.any():
        k = int(np.argmax(bad))
        raise StoreError(
            f"{path}: vertex {k} of {n} has a NaN or infinite position, colour, rotation or "
            f"opacity, or a position or scale past float32's range ({int(bad.sum())} such "
            "vertices); drop them where the file was made, then read it again."
        )
    return GaussianSet(
        means,
        covs,
        np.clip(colors, 0.0, 1.0),
        opacities,
        np.ones(n, dtype=np.uint32),
    )
