"""Named adapters from other pose conventions to `Pose` (OpenCV camera, z-up world).

Each convention is converted once at the boundary; the core never guesses.
"""

from __future__ import annotations

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.camera import Pose
from glmap_tools.geometry.rotations import rotations_from_quaternions

# OpenGL camera (x right, y up, z backward) -> OpenCV camera (x right, y down, z forward).
OPENCV_FROM_OPENGL_CAMERA = np.diag([1.0, -1.0, -1.0])

# A y-up world (Habitat, glTF) -> our z-up world: (x, y, z) -> (x, -z, y).
ZUP_FROM_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

_UP_AXES = {
    "x": np.array([1.0, 0, 0]),
    "-x": np.array([-1.0, 0, 0]),
    "y": np.array([0, 1.0, 0]),
    "-y": np.array([0, -1.0, 0]),
    "z": np.array([0, 0, 1.0]),
    "-z": np.array([0, 0, -1.0]),
}


def _as_matrix(m: np.ndarray) -> np.ndarray:
    arr = np.asarray(m, dtype=np.float64)
    if arr.shape != (4, 4):
        raise InvalidInputError(f"pose has shape {arr.shape}; pass a 4x4 matrix.")
    return arr


def from_opencv(world_from_camera: np.ndarray) -> Pose:
    """Already in our conventions (OpenCV camera, z-up world)."""
    return Pose(_as_matrix(world_from_camera))


def from_opengl(world_from_camera_gl: np.ndarray) -> Pose:
    """From an OpenGL camera (y up, looking down -z) in a z-up world."""
    m = _as_matrix(world_from_camera_gl).copy()
    m[:3, :3] = m[:3, :3] @ OPENCV_FROM_OPENGL_CAMERA
    return Pose(m)


def world_zup_from_up_axis(up: str) -> np.ndarray:
    """The [3, 3] rotation taking a world whose up axis is `up` to a z-up world."""
    if up not in _UP_AXES:
        raise InvalidInputError(
            f"up axis {up!r} is not one of {sorted(_UP_AXES)}; name the dataset world's up axis."
        )
    a = _UP_AXES[up]
    z = np.array([0.0, 0.0, 1.0])
    if np.allclose(a, z):
        return np.eye(3)
    if np.allclose(a, -z):
        return np.diag([1.0, -1.0, -1.0])
    if up == "y":
        return ZUP_FROM_YUP.copy()
    # Rodrigues rotation taking a onto z.
    v = np.cross(a, z)
    c = float(a @ z)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def from_dataset(world_from_camera: np.ndarray, up: str, camera: str = "opencv") -> Pose:
    """From a dataset's own world with up axis `up` and camera convention `opencv`|`opengl`."""
    m = _as_matrix(world_from_camera).copy()
    if camera == "opengl":
        m[:3, :3] = m[:3, :3] @ OPENCV_FROM_OPENGL_CAMERA
    elif camera != "opencv":
        raise InvalidInputError(f"camera convention {camera!r} is not 'opencv' or 'opengl'.")
    w = np.eye(4)
    w[:3, :3] = world_zup_from_up_axis(up)
    return Pose(w @ m)


def from_habitat(position: np.ndarray, rotation_wxyz: np.ndarray) -> Pose:
    """From a Habitat sensor state: y-up world, OpenGL camera, quaternion (w, x, y, z)."""
    r = rotations_from_quaternions(np.asarray(rotation_wxyz, dtype=np.float64))[0]
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = np.asarray(position, dtype=np.float64).reshape(3)
    return from_dataset(m, up="y", camera="opengl")


def to_opengl(pose: Pose) -> np.ndarray:
    """The same camera as an OpenGL world_from_camera (for pyrender)."""
    m = pose.matrix.copy()
    m[:3, :3] = m[:3, :3] @ OPENCV_FROM_OPENGL_CAMERA
    return m
