"""Quaternion to rotation matrix, the one formula every convention adapter shares."""

from __future__ import annotations

import numpy as np

from glmap_tools.errors import InvalidInputError


def rotations_from_quaternions(q: np.ndarray) -> np.ndarray:
    """[N, 3, 3] rotation matrices of [N, 4] quaternions (w, x, y, z), normalised first.

    Raises:
        InvalidInputError: a quaternion that is not finite or is zero.
    """
    q = np.asarray(q, dtype=np.float64).reshape(-1, 4)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    if not (np.all(np.isfinite(norm)) and np.all(norm > 1e-9)):
        k = int(np.argmax(~(np.isfinite(norm[:, 0]) & (norm[:, 0] > 1e-9))))
        raise InvalidInputError(
            f"quaternion {q[k].tolist()} (w, x, y, z) must be finite and non-zero."
        )
    w, x, y, z = (q / norm).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )
