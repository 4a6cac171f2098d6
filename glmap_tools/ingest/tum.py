"""Reader for TUM RGB-D folders (rgb.txt, depth.txt, groundtruth.txt).

Layout::

    rgb.txt           "timestamp rgb/xxx.png" per line, '#' comments
    depth.txt         "timestamp depth/xxx.png" per line; uint16 PNG, 5000 units per metre
    groundtruth.txt   "timestamp tx ty tz qx qy qz qw": camera-to-world (OpenCV camera)

Colour and depth frames are paired one-to-one by nearest timestamps (greedy, closest pairs
first, at most `MAX_TIME_DIFFERENCE` apart, as TUM's associate.py does); each pair takes the
ground-truth pose nearest in time within the same limit. Frames with no partner are dropped
and counted. The TUM (motion-capture) world is taken as z-up.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics
from glmap_tools.geometry.rotations import rotations_from_quaternions
from glmap_tools.ingest.source import PRIMESENSE, FrameSource, ParsedFolder, text_lines

MAX_TIME_DIFFERENCE = 0.02  # seconds
TUM_DEPTH_SCALE = 5000.0
TUM_UP_AXIS = "z"
REQUIRED = "rgb.txt, depth.txt and groundtruth.txt"

# Calibrated colour intrinsics published with the dataset (distortion ignored).
FREIBURG_INTRINSICS = {
    1: Intrinsics(517.3, 516.5, 318.6, 255.3, 640, 480),
    2: Intrinsics(520.9, 521.0, 325.1, 249.7, 640, 480),
    3: Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480),
}
_FREIBURG_NAME = re.compile(r"(?:freiburg|fr)([123])(?![0-9])")


def is_tum(folder: Path) -> bool:
    """True when `folder` has rgb.txt, depth.txt and groundtruth.txt."""
    return all((folder / name).is_file() for name in ("rgb.txt", "depth.txt", "groundtruth.txt"))


def default_intrinsics(folder: Path) -> tuple[Intrinsics, str]:
    """freiburg1/2/3 intrinsics when the folder name says which camera, else the ROS default."""
    found = _FREIBURG_NAME.search(folder.resolve().name.lower())
    if found:
        n = int(found.group(1))
        return FREIBURG_INTRINSICS[n], f"default TUM freiburg{n}"
    return PRIMESENSE, "default ROS fx=fy=525 cx=319.5 cy=239.5"


def quaternion_to_matrix(qx: float, qy: float, qz: float, qw: float) -> np.ndarray:
    """[3, 3] rotation of the unit quaternion (x, y, z, w), normalised first.

    Raises:
        InvalidInputError: the quaternion is zero or not finite.
    """
    q = np.array([qx, qy, qz, qw], dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if not math.isfinite(norm) or norm < 1e-9:
        raise InvalidInputError(
            f"quaternion (qx, qy, qz, qw) = {q.tolist()} must be finite and non-zero."
        )
    return rotations_from_quaternions(np.array([qw, qx, qy, qz]))[0]


def _read_table(path: Path, columns: int) -> list[tuple[int, list[str]]]:
    """(line number, tokens) of each data line; '#' lines and blanks are skipped."""
    rows = []
    for n, line in enumerate(text_lines(path), 1):
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        if len(tokens) != columns:
            raise InvalidInputError(
                f"{str(path)!r} line {n} has {len(tokens)} fields, expected {columns}: {line!r}."
            )
        rows.append((n, tokens))
    return rows


def _stamp(path: Path, n: int, token: str) -> float:
    try:
        value = float(token)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InvalidInputError(f"{str(path)!r} line {n}: timestamp {token!r} is not a number.")
    return value


def read_file_list(path: Path) -> list[tuple[float, str]]:
    """(timestamp, relative file name) of each line of rgb.txt / depth.txt."""
    return [(_stamp(path, n, t[0]), t[1]) for n, t in _read_table(path, 2)]


def read_groundtruth(path: Path) -> list[tuple[float, np.ndarray, str]]:
    """(timestamp, [4, 4] camera-to-world, where) of each line of groundtruth.txt."""
    poses = []
    for n, tokens in _read_table(path, 8):
        stamp = _stamp(path, n, tokens[0])
        try:
            tx, ty, tz, qx, qy, qz, qw = (float(t) for t in tokens[1:])
        except ValueError as err:
            raise InvalidInputError(
                f"{str(path)!r} line {n}: 'tx ty tz qx qy qz qw' must be numbers ({err})."
            ) from err
        where = f"groundtruth.txt line {n}"
        try:
            rotation = quaternion_to_matrix(qx, qy, qz, qw)
        except InvalidInputError as err:
            raise InvalidInputError(f"{where}: {err}") from err
        m = np.eye(4)
        m[:3, :3] = rotation
        m[:3, 3] = (tx, ty, tz)
        poses.append((stamp, m, where))
    return poses


def associate(
    first: list[float], second: list[float], max_difference: float = MAX_TIME_DIFFERENCE
) -> list[tuple[int, int]]:
    """One-to-one pairs (i, j) of nearest timestamps, closest first, |a - b| <= max_difference.

    Returns the pairs sorted by `first` index.
    """
    b = np.asarray(second, dtype=np.float64)
    order = np.argsort(b, kind="stable")
    b_sorted = b[order]
    candidates = []
    for i, a in enumerate(first):
        lo = int(np.searchsorted(b_sorted, a - max_difference, side="left"))
        hi = int(np.searchsorted(b_sorted, a + max_difference, side="right"))
        for k in range(lo, hi):
            candidates.append((abs(a - float(b_sorted[k])), i, int(order[k])))
    candidates.sort()
    used_first: set[int] = set()
    used_second: set[int] = set()
    pairs = []
    for diff, i, j in candidates:
        if diff <= max_difference and i not in used_first and j not in used_second:
            used_first.add(i)
            used_second.add(j)
            pairs.append((i, j))
    return sorted(pairs)


def nearest(stamps: np.ndarray, t: float, max_difference: float) -> int | None:
    """Index of the sorted `stamps` entry nearest `t`, or None when farther than the limit."""
    k = int(np.searchsorted(stamps, t))
    best = None
    for c in (k - 1, k):
        if 0 <= c < len(stamps) and (best is None or abs(stamps[c] - t) < abs(stamps[best] - t)):
            best = c
    if best is None or abs(stamps[best] - t) > max_difference:
        return None
    return best


def parse_tum(folder: Path) -> ParsedFolder:
    """Read a TUM RGB-D folder: associated frames, ground-truth poses, default intrinsics.

    Raises:
        InvalidInputError: malformed lines, a bad quaternion, or no frame that has a depth
            image and a pose within `MAX_TIME_DIFFERENCE` seconds.
    """
    rgbs = read_file_list(folder / "rgb.txt")
    depths = read_file_list(folder / "depth.txt")
    truth = sorted(read_groundtruth(folder / "groundtruth.txt"), key=lambda r: r[0])
    truth_stamps = np.array([r[0] for r in truth], dtype=np.float64)
    frames: list[FrameSource] = []
    for i, j in associate([s for s, _ in rgbs], [s for s, _ in depths]):
        stamp = rgbs[i][0]
        k = nearest(truth_stamps, stamp, MAX_TIME_DIFFERENCE)
        if k is None:
            continue
        _, matrix, where = truth[k]
        frames.append(
            FrameSource(
                len(frames), folder / rgbs[i][1], folder / depths[j][1], matrix, where, stamp
            )
        )
    if not frames:
        raise InvalidInputError(
            f"TUM folder {str(folder)!r}: no colour frame has a depth image and a ground-truth "
            f"pose within {MAX_TIME_DIFFERENCE} s ({len(rgbs)} colour, {len(depths)} depth, "
            f"{len(truth)} poses); check that the three files cover the same time span."
        )
    intrinsics, source = default_intrinsics(folder)
    return ParsedFolder(
        "tum",
        frames,
        intrinsics,
        source,
        TUM_DEPTH_SCALE,
        TUM_UP_AXIS,
        dropped=len(rgbs) - len(frames),
    )
