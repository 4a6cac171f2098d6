"""An MLLM names the geometric segments (`--perception geometric+mllm`, issue 11 item 3).

The model sees the frame's numbered contact sheet (`perception.sheet`) and each segment's
size and height, and answers with objects (segment ids, label, description) and groups, in
the same shape `label_segments` takes from an MCP client. Replies that name unknown or
repeated segment ids are sent back once with the reason (`chat_structured`).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pydantic import BaseModel, Field

from glmap_tools.language.llm import LLMClient, chat_structured
from glmap_tools.language.prompts import PromptSet, default_prompts
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS
from glmap_tools.perception.labelling import SegmentGroup, SegmentLabel, semantics_from_labels
from glmap_tools.perception.semantics import FrameSemantics

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.perception.geometric import GeometricConfig, Segment

# Imports inside functions stay there: pIL, scipy load on first use; optional: PIL.

PROMPT = "segment_naming"


class NamedObject(BaseModel):
    """One object the model names: its segments, label and description."""

    segments: list[int] = Field(min_length=1)
    label: str = Field(min_length=1, max_length=200)
    description: str = Field(default="", max_length=MAX_DESCRIPTION_CHARS)


class NamedGroup(BaseModel):
    """One region the model sees: member segment ids and a description."""

    members: list[int] = Field(min_length=1)
    description: str = Field(min_length=1, max_length=MAX_DESCRIPTION_CHARS)


class SegmentNames(BaseModel):
    """The model's reply."""

    objects: list[NamedObject] = Field(default_factory=list)
    groups: list[NamedGroup] = Field(default_factory=list)


def segment_lines(segments: Sequence[Segment], floor_z: float) -> str:
    """One prompt line per segment: `id: w x d x h m, top t m`."""
    lines = []
    for s in segments:
        w, d, h = (float(v) for v in s.size)
        lines.append(f"{s.id}: {w:.2f} x {d:.2f} x {h:.2f} m, top {float(s.hi[2]) - floor_z:.2f} m")
    return "\n".join(lines)


def _checker(segments: Sequence[Segment]):  # type: ignore[no-untyped-def]
    known = {s.id for s in segments}

    def check(reply: SegmentNames) -> None:
        ids = [i for o in reply.objects for i in o.segments]
        unknown = sorted(set(ids) - known)
        repeated = sorted({i for i in ids if ids.count(i) > 1})
        named = set(ids)
        outside = sorted({m for g in reply.groups for m in g.members} - named)
        problems = []
        if unknown:
            problems.append(f"segment ids {unknown} do not exist (ids: {sorted(known)})")
        if repeated:
            problems.append(f"segment ids {repeated} are used by more than one object")
        if outside:
            problems.append(f"group members {outside} are not segments of a listed object")
        if problems:
            raise ValueError("; ".join(problems))

    return check


@dataclass
class MLLMSegmentNamer:
    """Geometric segments named by a vision LLM: a `PerceptionBackend` (frame -> semantics).

    Args:
        client: a vision chat model (e.g. `OllamaClient(..., vision=True)`).
        prompts: where the `segment_naming` prompt comes from.
        config: the segmenter settings.
        retries: corrective retries of a reply that does not fit the segments.
    """

    client: LLMClient
    prompts: PromptSet | None = None
    config: GeometricConfig | None = None
    retries: int = 1
    calls: int = 0

    def name(
        self, frame: RGBDFrame, segments: Sequence[Segment]
    ) -> tuple[list[SegmentLabel], list[SegmentGroup]]:
        """Ask the model for the segments' names.

        Raises:
            LLMOutputError: no usable reply after the retries.
        """
        from PIL import Image

        from glmap_tools.perception.sheet import segment_sheet

        prompt = (self.prompts or default_prompts()).get(PROMPT)
        floor_z = float(min(s.lo[2] for s in segments))
        buffer = io.BytesIO()
        Image.fromarray(segment_sheet(frame.rgb, segments)).save(buffer, format="PNG")
        message = {
            "role": "user",
            "content": prompt.format(segments=segment_lines(segments, floor_z)),
            "images": [buffer.getvalue()],
        }
        self.calls += 1
        reply, _ = chat_structured(
            self.client,
            [message],
            SegmentNames,
            prompt=prompt,
            check=_checker(segments),
            retries=self.retries,
        )
        labels = [SegmentLabel(tuple(o.segments), o.label, o.description) for o in reply.objects]
        groups = [SegmentGroup(tuple(g.members), g.description) for g in reply.groups]
        return labels, groups

    def __call__(self, frame: RGBDFrame) -> FrameSemantics:
        """Segment `frame` and name its segments (no segment: no model call)."""
        from glmap_tools.perception.geometric import segment_frame

        segments = segment_frame(frame, self.config)
        if not segments:
            return FrameSemantics()
        labels, groups = self.name(frame, segments)
        return semantics_from_labels(segments, labels, groups)
