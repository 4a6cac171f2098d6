"""What instance and region matching share: the frame's context, text candidates, report fixes."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from glmap_tools.language.text_merger import DELIMITER, TextMerger, append_text
from glmap_tools.map.report import UnitChange, UpdateReport

TextMerge = Callable[[str, str], str]  # (buffer, description) -> buffer


@dataclass(frozen=True)
class Matching:
    """The settings one frame's matching reads (the map itself is passed as its units).

    Attributes:
        frame_index: the frame being planned.
        tau_s: the text-similarity threshold.
        merge_text: appends a description to a text buffer (`buffered_text`).
    """

    frame_index: int
    tau_s: float
    merge_text: TextMerge


def buffered_text(merger: TextMerger, max_words: int, buffer: str, text: str) -> str:
    """`buffer` with `text` appended; past `max_words` words `merger` rewrites it."""
    merged = append_text(buffer, text)
    if len(merged.split()) > max_words:
        merged = merger.merge(merged.split(DELIMITER), max_words)
    return merged


def text_candidates(
    ids: np.ndarray, matrix: np.ndarray, embedding: np.ndarray, tau: float
) -> list[tuple[float, int]]:
    """(cosine, id) of the map's units whose text is similar (cos > tau), best first.

    Only units that existed before the frame are candidates: two objects (or groups)
    perception told apart in one frame stay apart, though both may merge into one unit.

    Args:
        ids: [N] unit ids.
        matrix: [N, D] their embeddings.
        embedding: [D] the observation's embedding.
        tau: the text-similarity threshold tau_s.
    """
    if len(ids) == 0:
        return []
    sims = matrix @ embedding
    keep = np.flatnonzero(sims > tau)
    return sorted(((float(sims[i]), int(ids[i])) for i in keep), key=lambda c: (-c[0], c[1]))


def report_fused(
    added: list[UnitChange],
    merged: list[UnitChange],
    absorbed: dict[int, int],
    removed: set[int],
    report: UpdateReport,
) -> None:
    """Point the report at surviving ids; a unit added and fused at once counts as merged.

    Args:
        added: the report's added changes of this kind.
        merged: the report's merged changes of this kind.
        absorbed: fused unit id -> the unit it became.
        removed: the fused ids that were map units before the frame.
        report: the frame's report (its `fused` gains `removed`).
    """
    report.fused.update({i: s for i, s in absorbed.items() if i in removed})
    for change in merged:
        change.global_id = absorbed.get(change.global_id, change.global_id)
    for change in [c for c in added if c.global_id in absorbed]:
        added.remove(change)
        change.global_id = absorbed[change.global_id]
        merged.append(change)
