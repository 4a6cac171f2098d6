"""Reader for Redwood / Open3D-style RGB-D folders (e.g. the bundled ICL-NUIM living room).

Layout::

    color/*.jpg|png   (or image/, rgb/)   colour frames
    depth/*.png                            uint16 depth, millimetres (depth scale 1000)
    trajectory.log                         camera-to-world 4x4 per frame: a header line
                                           "i j n", then 4 matrix rows
    rgbd.match        (optional)           "depth/xxx.png color/xxx.jpg" per line
    camera_primesense.json or *.json       (optional) {"width", "height",
                                           "intrinsic_matrix": column-major 3x3}

Poses use the OpenCV camera; the Redwood/ICL-NUIM world is y-up.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Intrinsics
from glmap_tools.ingest.source import PRIMESENSE, FrameSource, ParsedFolder, text_lines

COLOR_DIRS = ("color", "image", "rgb")
COLOR_SUFFIXES = (".jpg", ".jpeg", ".png")
REDWOOD_DEPTH_SCALE = 1000.0
REDWOOD_UP_AXIS = "y"
REQUIRED = "trajectory.log, depth/*.png and color/*.jpg|png"


def is_redwood(folder: Path) -> bool:
    """True when `folder` has a trajectory.log and a depth/ folder."""
    return (folder / "trajectory.log").is_file() and (folder / "depth").is_dir()


def read_trajectory_log(path: Path) -> list[np.ndarray]:
    """Parse a trajectory.log into [4, 4] float64 matrices (header line + 4 rows each).

    Raises:
        InvalidInputError: a block is truncated or holds non-numeric values.
    """
    lines = [(n, ln.split()) for n, ln in enumerate(text_lines(path), 1)]
    lines = [(n, tokens) for n, tokens in lines if tokens]
    if len(lines) % 5:
        raise InvalidInputError(
            f"{str(path)!r} has {len(lines)} non-empty lines, not a multiple of 5; each frame "
            "needs a header line 'i j n' followed by the 4 rows of its 4x4 camera-to-world pose."
        )
    poses = []
    for start in range(0, len(lines), 5):
        block = lines[start + 1 : start + 5]
        try:
            rows = [[float(t) for t in tokens] for _, tokens in block]
            if any(len(r) != 4 for r in rows):
                raise ValueError("row length")
        except ValueError as err:
            raise InvalidInputError(
                f"{str(path)!r} lines {block[0][0]}-{block[-1][0]} are not 4 rows of 4 numbers; "
                "fix the pose matrix of that frame."
            ) from err
        poses.append(np.array(rows, dtype=np.float64))
    return poses


def read_intrinsics_json(path: Path) -> Intrinsics:
    """Read Open3D's PinholeCameraIntrinsic JSON (column-major `intrinsic_matrix`)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        k = np.asarray(data["intrinsic_matrix"], dtype=np.float64).reshape(3, 3).T
        width, height = data["width"], data["height"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise InvalidInputError(
            f"camera file {str(path)!r} is not valid ({err!r}); write "
            '{"width": 640, "height": 480, "intrinsic_matrix": [fx, 0, 0, 0, fy, 0, cx, cy, 1]} '
            "(column-major, as Open3D saves it)."
        ) from err
    if not (isinstance(width, int) and isinstance(height, int)):
        raise InvalidInputError(
            f"camera file {str(path)!r} has width={width!r}, height={height!r}; use integers."
        )
    return Intrinsics(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]), width, height)


def find_intrinsics(folder: Path) -> tuple[Intrinsics, str]:
    """The folder's camera JSON (camera_primesense.json first), else the PrimeSense default."""
    preferred = folder / "camera_primesense.json"
    candidates = [preferred] if preferred.is_file() else []
    for path in sorted(folder.glob("*.json")):
        if path != preferred and "intrinsic_matrix" in path.read_text(errors="replace"):
            candidates.append(path)
    if candidates:
        return read_intrinsics_json(candidates[0]), candidates[0].name
    return PRIMESENSE, "default PrimeSense fx=fy=525 cx=319.5 cy=239.5"


def declared_up_axis(folder: Path) -> str | None:
    """The world up axis a camera JSON declares with an "up_axis" key (glmap tours write "z")."""
    for path in sorted(folder.glob("*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and "intrinsic_matrix" in data and "up_axis" in data:
            return str(data["up_axis"])
    return None


def _color_dir(folder: Path) -> Path:
    for name in COLOR_DIRS:
        if (folder / name).is_dir():
            return folder / name
    raise InvalidInputError(
        f"Redwood folder {str(folder)!r} has no colour folder (looked for "
        f"{', '.join(n + '/' for n in COLOR_DIRS)}); a Redwood sequence needs {REQUIRED}."
    )


def _image_pairs(folder: Path) -> list[tuple[Path, Path]]:
    """(colour, depth) paths in frame order, from rgbd.match or by sorted file names."""
    match = folder / "rgbd.match"
    if match.is_file():
        pairs = []
        for n, line in enumerate(text_lines(match), 1):
            tokens = line.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            if len(tokens) != 2:
                raise InvalidInputError(
                    f"{str(match)!r} line {n} is {line!r}; each line names two files, "
                    "'depth/xxx.png color/xxx.jpg'."
                )
            first, second = tokens
            # The Redwood layout lists depth first; honour an explicit folder name either way.
            if Path(second).parts[0] == "depth" and Path(first).parts[0] != "depth":
                first, second = second, first
            pairs.append((folder / second, folder / first))
        return pairs
    color_dir = _color_dir(folder)
    colors = sorted(p for p in color_dir.iterdir() if p.suffix.lower() in COLOR_SUFFIXES)
    depths = sorted((folder / "depth").glob("*.png"))
    if len(colors) != len(depths):
        raise InvalidInputError(
            f"Redwood folder {str(folder)!r} has {len(colors)} colour and {len(depths)} depth "
            "images; give each colour frame one depth PNG, or list the pairs in rgbd.match."
        )
    return list(zip(colors, depths, strict=True))


def parse_redwood(folder: Path) -> ParsedFolder:
    """Read a Redwood / Open3D-style folder's frame list, poses and intrinsics.

    Raises:
        InvalidInputError: no colour folder, unequal image counts, a malformed
            trajectory.log or camera JSON, or a different number of poses and images.
    """
    pairs = _image_pairs(folder)
    log = folder / "trajectory.log"
    poses = read_trajectory_log(log)
    if len(poses) != len(pairs):
        raise InvalidInputError(
            f"{str(log)!r} has {len(poses)} poses but the folder has {len(pairs)} image pairs; "
            "give one pose per frame (trim the log or the images so they match)."
        )
    intrinsics, source = find_intrinsics(folder)
    up_axis = declared_up_axis(folder) or REDWOOD_UP_AXIS
    frames = [
        FrameSource(i, rgb, depth, pose, f"trajectory.log frame {i}")
        for i, ((rgb, depth), pose) in enumerate(zip(pairs, poses, strict=True))
    ]
    return ParsedFolder("redwood", frames, intrinsics, source, REDWOOD_DEPTH_SCALE, up_axis)
