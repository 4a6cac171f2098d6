"""Names for geometric segments given in a file, by pointing at pixels (`glmap build --labels`).

Segment ids depend on the segmenter, so a labels file points instead: each object lists one
or more pixels `[x, y]` (column, row) of the full-resolution image, and every segment that
holds one of them is that object (several points name the pieces of one object)::

    {"frames": {
        "00000": {
            "objects": [{"id": 1, "at": [[412, 300]], "label": "lounge chair",
                         "description": "a white lounge chair"}],
            "groups": [{"id": 1, "description": "a reading corner", "members": [1]}]}}}

Frames are keyed by the colour image's file stem. Segments nobody points at are left out.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.perception.labelling import SegmentGroup, SegmentLabel

if TYPE_CHECKING:
    from glmap_tools.perception.geometric import Segment

# Imports inside functions stay there: scipy load on first use: `glmap` imports every command module
# to build its parser; optional: PIL.

NEAR = 6  # pixels: a point just off a segment (its edge) still names it


@dataclass(frozen=True)
class PointedObject:
    """One object of a labels file: the pixels that point at it, its words."""

    id: int
    at: tuple[tuple[int, int], ...]  # (x, y) pixels
    label: str
    description: str


@dataclass(frozen=True)
class FrameLabels:
    """The pointed objects and groups (members: object ids) of one frame."""

    objects: tuple[PointedObject, ...]
    groups: tuple[tuple[int, str, tuple[int, ...]], ...]


def _fail(where: str, problem: str) -> InvalidInputError:
    return InvalidInputError(
        f"labels file: {where} {problem} (see glmap_tools.perception.labels_file)."
    )


def _ints(value: Any, where: str) -> list[int]:
    if not isinstance(value, list) or not all(
        isinstance(v, int) and not isinstance(v, bool) for v in value
    ):
        raise _fail(where, f"must be a list of integers, got {value!r}")
    return value


def _frame(entry: Any, where: str) -> FrameLabels:
    if not isinstance(entry, Mapping):
        raise _fail(where, "must be an object with 'objects' and 'groups'")
    for key in ("objects", "groups"):
        if not isinstance(entry.get(key, []), list):
            raise _fail(f"{where}.{key}", f"must be a list, got {str(entry[key])[:80]}")
    objects = []
    for i, obj in enumerate(entry.get("objects", [])):
        w = f"{where}.objects[{i}]"
        if not isinstance(obj, Mapping):
            raise _fail(w, "must be an object")
        points = obj.get("at")
        if not isinstance(points, list) or not points:
            raise _fail(w, "needs 'at': a list of [x, y] pixels")
        at = []
        for p in points:
            xy = _ints(p, f"{w}.at")
            if len(xy) != 2 or min(xy) < 0:
                raise _fail(f"{w}.at", f"has {p!r}; each point is [x, y] with x, y >= 0")
            at.append((xy[0], xy[1]))
        label = str(obj.get("label", "")).strip()
        if not label:
            raise _fail(w, "has an empty label")
        oid = obj.get("id")
        if not isinstance(oid, int) or isinstance(oid, bool):
            raise _fail(w, f"needs an integer 'id', got {oid!r}")
        objects.append(PointedObject(oid, tuple(at), label, str(obj.get("description", ""))))
    groups = []
    for k, group in enumerate(entry.get("groups", [])):
        w = f"{where}.groups[{k}]"
        if not isinstance(group, Mapping) or not str(group.get("description", "")).strip():
            raise _fail(w, "needs a 'description' and 'members'")
        members = tuple(_ints(group.get("members"), f"{w}.members"))
        groups.append((k + 1, str(group["description"]), members))
    return FrameLabels(tuple(objects), tuple(groups))


def load_labels_file(path: Path) -> dict[str, FrameLabels]:
    """Read and check a labels file; frame stem -> its labels.

    Raises:
        InvalidInputError: an unreadable file or a malformed entry (named).
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:  # ValueError: not UTF-8, or not JSON
        raise InvalidInputError(f"labels file {str(path)!r} cannot be read as JSON: {exc}") from exc
    if not isinstance(data, Mapping) or not isinstance(data.get("frames"), Mapping):
        raise InvalidInputError(
            f"labels file {str(path)!r} needs {{'frames': {{stem: {{'objects': [...]}}}}}}."
        )
    return {str(stem): _frame(entry, f"frames[{stem!r}]") for stem, entry in data["frames"].items()}


def _segments_at(segments: Sequence[Segment], x: int, y: int) -> list[Segment]:
    """The segment holding pixel (x, y), else those within NEAR pixels of it."""
    exact = [s for s in segments if y < s.mask.shape[0] and x < s.mask.shape[1] and s.mask[y, x]]
    if exact:
        return exact
    y0, x0 = max(0, y - NEAR), max(0, x - NEAR)
    return [s for s in segments if s.mask[y0 : y + NEAR + 1, x0 : x + NEAR + 1].any()]


def pointed_labels(
    segments: Sequence[Segment], frame_labels: FrameLabels
) -> tuple[list[SegmentLabel], list[SegmentGroup], list[int]]:
    """(labels, groups, ids of objects that point at no segment) for one frame's segments.

    A segment pointed at by two objects goes to the first.
    """
    taken: set[int] = set()
    labels: list[SegmentLabel] = []
    first_segment: dict[int, int] = {}
    missing = []
    for obj in frame_labels.objects:
        ids = []
        for x, y in obj.at:
            for seg in _segments_at(segments, x, y):
                if seg.id not in taken and seg.id not in ids:
                    ids.append(seg.id)
        if not ids:
            missing.append(obj.id)
            continue
        taken.update(ids)
        first_segment[obj.id] = ids[0]
        labels.append(SegmentLabel(tuple(ids), obj.label, obj.description))
    groups = []
    for _, description, members in frame_labels.groups:
        mine = tuple(first_segment[m] for m in members if m in first_segment)
        if mine:
            groups.append(SegmentGroup(mine, description))
    return labels, groups, missing


def interior_points(mask: Any, count: int = 3, spacing: int = 60) -> list[list[int]]:
    """Up to `count` [x, y] pixels deep inside an [H, W] bool mask, `spacing` pixels apart."""
    from scipy import ndimage

    depth = ndimage.distance_transform_edt(mask)
    rows, cols = np.ogrid[: mask.shape[0], : mask.shape[1]]
    points = []
    for _ in range(count):
        y, x = np.unravel_index(int(np.argmax(depth)), depth.shape)
        if depth[y, x] < 4:
            break
        points.append([int(x), int(y)])
        depth[(rows - y) ** 2 + (cols - x) ** 2 < spacing**2] = 0
    return points


def labels_from_annotations(folder: Path, skip: Sequence[str] = ("floor", "wall")) -> dict:
    """A labels file pointing at a dataset's annotated objects (those labelled `skip` left out).

    How the bundled `redwood_livingroom1_5frames.labels.json` is made: `python -m
    glmap_tools.perception.labels_file FOLDER > FOLDER.labels.json` (beside the
    folder: a camera JSON is looked for inside it).
    """
    from PIL import Image

    frames = {}
    for path in sorted((Path(folder) / "annotations").glob("*.json")):
        annotation = json.loads(path.read_text())
        mask = np.asarray(Image.open(path.with_suffix(".png")))
        objects = [
            {
                "id": o["id"],
                "at": interior_points(mask == o["id"]),
                "label": o["label"],
                "description": o.get("description", ""),
            }
            for o in annotation["objects"]
            if o["label"] not in skip
        ]
        kept = {o["id"] for o in objects}
        groups = [
            {**g, "members": [m for m in g["members"] if m in kept]}
            for g in annotation.get("groups", [])
            if any(m in kept for m in g["members"])
        ]
        frames[path.stem] = {"objects": objects, "groups": groups}
    return {
        "source": "points inside the hand-annotated masks of annotations/ (floor and wall left "
        "out), made by glmap_tools.perception.labels_file.labels_from_annotations",
        "frames": frames,
    }


if __name__ == "__main__":
    import sys

    print(json.dumps(labels_from_annotations(Path(sys.argv[1])), indent=1))
