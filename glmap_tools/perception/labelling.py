"""Names for class-agnostic segments: from the calling agent, a labels file or ground truth.

A `SegmentLabel` names one object made of one or more segments of a frame (a segmenter may
cut one object into pieces: a sofa's seat and back); `semantics_from_labels` turns the
labels and groups into the `FrameSemantics` that `GLMap.integrate` fuses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS
from glmap_tools.perception.semantics import FrameSemantics, GroupObservation, ObjectObservation

if TYPE_CHECKING:
    from glmap_tools.perception.geometric import Segment

IGNORE = "ignore"


@dataclass(frozen=True)
class SegmentLabel:
    """One named object: the segments it is made of, a short label and a description."""

    segments: tuple[int, ...]
    label: str
    description: str = ""


@dataclass(frozen=True)
class SegmentGroup:
    """A region: the labelled objects it holds (by their first segment id), a description."""

    members: tuple[int, ...]
    description: str


def semantics_from_labels(
    segments: Sequence[Segment],
    labels: Sequence[SegmentLabel],
    groups: Sequence[SegmentGroup] = (),
) -> FrameSemantics:
    """FrameSemantics of the labelled segments (label "ignore" leaves a segment out).

    The object's local id is its first segment id; a group's members are segment ids of
    labelled objects.

    Raises:
        UnknownIdError: a segment id the frame does not have.
        InvalidInputError: a segment labelled twice, an empty label, an overlong
            description, a group member that is not a labelled object.
    """
    by_id = {s.id: s for s in segments}
    used: dict[int, int] = {}
    objects: list[ObjectObservation] = []
    for i, entry in enumerate(labels):
        if not entry.segments:
            raise InvalidInputError(f"labels[{i}] lists no segment; give at least one id.")
        for sid in entry.segments:
            if sid not in by_id:
                raise UnknownIdError(
                    f"labels[{i}] names segment {sid}, but this frame's segments are "
                    f"{sorted(by_id)}."
                )
            if sid in used:
                raise InvalidInputError(
                    f"segment {sid} is labelled twice (labels[{used[sid]}] and labels[{i}]); "
                    "list each segment once (one entry may list several segments)."
                )
            used[sid] = i
        label = entry.label.strip()
        if not label:
            raise InvalidInputError(
                f"labels[{i}] (segments {list(entry.segments)}) has an empty label; give a "
                f"short category such as 'chair', or {IGNORE!r} to leave it out."
            )
        if len(entry.description) > MAX_DESCRIPTION_CHARS:
            raise InvalidInputError(
                f"labels[{i}] has a description of {len(entry.description)} characters; the "
                f"limit is {MAX_DESCRIPTION_CHARS}."
            )
        if label.lower() == IGNORE:
            continue
        mask = np.logical_or.reduce([by_id[s].mask for s in entry.segments])
        objects.append(ObjectObservation(entry.segments[0], label, entry.description.strip(), mask))
    object_ids = {o.local_id for o in objects}
    out_groups = []
    for k, group in enumerate(groups):
        members = []
        for m in group.members:
            owner = used.get(m)
            first = labels[owner].segments[0] if owner is not None else None
            if first is None or first not in object_ids:
                raise InvalidInputError(
                    f"groups[{k}] lists segment {m}, which is not a labelled object; members "
                    f"must be labelled segment ids of this frame {sorted(object_ids)}."
                )
            members.append(first)
        out_groups.append(GroupObservation(k + 1, group.description, tuple(dict.fromkeys(members))))
    semantics = FrameSemantics(objects, out_groups)
    if segments:
        semantics.validate(*segments[0].mask.shape)
    return semantics


def labels_by_overlap(
    segments: Sequence[Segment], truth: np.ndarray, names: dict[int, tuple[str, str]]
) -> list[SegmentLabel]:
    """Name each segment after the ground-truth object it overlaps most (an oracle labeller).

    Segments whose largest overlap is background (id 0) are ignored; segments that share
    an object become one label, as an agent would name the pieces of one object.

    Args:
        segments: the frame's segments.
        truth: [H, W] int ground-truth object ids, 0 = none.
        names: object id -> (label, description).
    """
    pieces: dict[int, list[int]] = {}
    for seg in segments:
        ids, counts = np.unique(truth[seg.mask], return_counts=True)
        best = int(ids[np.argmax(counts)])
        if best > 0 and best in names:
            pieces.setdefault(best, []).append(seg.id)
    return [
        SegmentLabel(tuple(ids), *names[obj])
        for obj, ids in sorted(pieces.items(), key=lambda p: p[1][0])
    ]


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two [H, W] bool masks (0 when both are empty)."""
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 0.0


def best_iou(truth_mask: np.ndarray, segments: Sequence[Segment]) -> float:
    """The IoU of the ground-truth mask with the segments that overlap it most (as one mask).

    Segments count as the object's when most of their pixels lie on it (how the oracle
    labeller names them).
    """
    mine = [s.mask for s in segments if np.logical_and(s.mask, truth_mask).sum() * 2 > s.pixels]
    if not mine:
        return 0.0
    return mask_iou(truth_mask, np.logical_or.reduce(mine))


def oracle_semantics(
    segments: Sequence[Segment], truth: FrameSemantics
) -> tuple[FrameSemantics, list[SegmentLabel]]:
    """The frame's segments named by ground truth (`labels_by_overlap`), groups carried over.

    Measures the segmenter alone: names are perfect, masks and splits are the segmenter's.

    Returns:
        (semantics to integrate, the labels given).
    """
    if not segments:
        return FrameSemantics(), []
    ids = np.zeros(segments[0].mask.shape, dtype=np.int64)
    for obj in truth.objects:
        ids[obj.mask] = obj.local_id
    names = {o.local_id: (o.label, o.description) for o in truth.objects}
    labels = labels_by_overlap(segments, ids, names)
    first_of: dict[int, int] = {}  # ground-truth object id -> its label's first segment
    seg_to_obj = {}
    for seg in segments:
        values, counts = np.unique(ids[seg.mask], return_counts=True)
        seg_to_obj[seg.id] = int(values[np.argmax(counts)])
    for lab in labels:
        first_of[seg_to_obj[lab.segments[0]]] = lab.segments[0]
    groups = []
    for group in truth.groups:
        members = tuple(first_of[m] for m in group.members if m in first_of)
        if members:
            groups.append(SegmentGroup(members, group.description))
    return semantics_from_labels(segments, labels, groups), labels
