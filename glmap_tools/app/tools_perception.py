"""Perception without a model (issue 11 item 3): the calling agent names geometric segments.

`observe_frame` without annotations (and no perception backend) calls `observe_unannotated`:
the frame's geometry and occupancy go into the map at once, its class-agnostic segments are
returned with a numbered contact sheet and wait as *pending*; `label_segments` names them and
fuses the labelled ones as instances (and groups as regions) through `GLMap.integrate`.

No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

import io
import threading
from typing import TYPE_CHECKING, Annotated

from pydantic import BaseModel, ConfigDict, Field

from glmap_tools.app.arguments import Description, Label, SessionArg
from glmap_tools.app.inputs import MAX_GROUPS, MAX_OBJECTS
from glmap_tools.app.results import ObserveResult, Picture
from glmap_tools.app.runtime import ADDS, AppState, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import Session, locked
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS
from glmap_tools.map.report import UpdateReport
from glmap_tools.perception.labelling import (
    IGNORE,
    SegmentGroup,
    SegmentLabel,
    semantics_from_labels,
)
from glmap_tools.perception.pending import PendingFrames, pending_bytes
from glmap_tools.perception.semantics import FrameSemantics

if TYPE_CHECKING:
    from glmap_tools.perception.geometric import Segment

# Imports inside functions stay there: pIL, scipy load on first use: the tools load before these do,
# in the server and the in-process toolset alike; optional: PIL.

SegmentId = Annotated[int, Field(ge=1)]
_pending_made = threading.Lock()


class PendingSegment(BaseModel):
    """One unnamed segment of a pending frame."""

    id: int
    pixels: int
    box: list[int] = Field(description="image box [row0, col0, row1, col1]")
    lo: list[float] = Field(description="world min corner (m, z up)")
    hi: list[float] = Field(description="world max corner (m)")


class PendingSegments(BaseModel):
    """Segments waiting for label_segments (the image shows each id)."""

    frame: str = Field(description="pass to label_segments")
    segments: list[PendingSegment]
    expires_in_s: float


class PendingObserveResult(ObserveResult):
    """Geometry and occupancy added; the segments wait for names."""

    pending: PendingSegments | None = Field(description="null: no segment found")
    sheet: Picture | None = Field(default=None, exclude=True)  # the numbered segments


class LabelInput(BaseModel):
    """One object: its segments (pieces of one object go together), label, description."""

    model_config = ConfigDict(extra="forbid")
    segments: list[SegmentId] = Field(min_length=1, max_length=MAX_OBJECTS)
    label: Label = Field(max_length=200, description=f"category, or {IGNORE!r}")
    description: Description = Field(default="", max_length=MAX_DESCRIPTION_CHARS)


class GroupInput(BaseModel):
    """A region: labelled segments that belong together, and its description."""

    model_config = ConfigDict(extra="forbid")
    members: list[SegmentId] = Field(min_length=1, max_length=MAX_OBJECTS)
    description: Description = Field(min_length=1, max_length=MAX_DESCRIPTION_CHARS)


def pending_frames(state: AppState) -> PendingFrames:
    """The server's pending frames (made on first use); a session's go when its map is
    replaced or the session ends."""
    with _pending_made:
        if state.pending is None:
            state.pending = PendingFrames()
            state.registry.on_drop.append(state.pending.forget)
        return state.pending


def _describe(segments: "list[Segment]") -> list[PendingSegment]:
    return [
        PendingSegment(
            id=s.id,
            pixels=s.pixels,
            box=list(s.box),
            lo=[round(float(v), 2) for v in s.lo],
            hi=[round(float(v), 2) for v in s.hi],
        )
        for s in segments
    ]


def _sheet_png(frame: RGBDFrame, segments: "list[Segment]") -> bytes:
    from PIL import Image as PILImage

    from glmap_tools.perception.sheet import segment_sheet

    buffer = io.BytesIO()
    PILImage.fromarray(segment_sheet(frame.rgb, segments)).save(buffer, format="PNG")
    return buffer.getvalue()


async def observe_unannotated(
    state: AppState, target: Session, frame: RGBDFrame
) -> PendingObserveResult:
    """Integrate `frame` as geometry, park its segments, return them with a contact sheet."""
    from glmap_tools.perception.geometric import segment_frame  # scipy: off the handshake

    store = pending_frames(state)
    # Room for the frame first: one past the memory cap is refused before any work.
    with store.room(target.handle, pending_bytes(*frame.depth.shape)):
        segments = (await in_thread(lambda: segment_frame(frame)))[:MAX_OBJECTS]
        result = await in_thread(lambda: _park(store, target, frame, segments))
    if segments:
        png = await in_thread(lambda: _sheet_png(frame, segments))
        result.sheet = Picture(format="png", data=png)
    return result


def _park(
    store: PendingFrames, target: Session, frame: RGBDFrame, segments: "list[Segment]"
) -> PendingObserveResult:
    """Integrate the frame's geometry and park its segments, under the map's lock."""
    with locked(target) as glmap:
        report = glmap.integrate(frame, FrameSemantics())
        pending = (
            store.add(target.handle, glmap, frame, segments, report.frame_index)
            if segments
            else None
        )
        name = target.live.name
    return PendingObserveResult(
        session=target.handle,
        map_name=name,
        summary=f"{report.summary()}; {len(segments)} segments wait for label_segments",
        report=report,
        pending=PendingSegments(
            frame=pending.token, segments=_describe(segments), expires_in_s=store.max_age_s
        )
        if pending is not None
        else None,
    )


async def label_segments(
    frame: Annotated[str, Field(max_length=32, description="pending.frame of observe_frame")],
    labels: Annotated[list[LabelInput], Field(max_length=MAX_OBJECTS)],
    call: Call,
    groups: Annotated[list[GroupInput], Field(max_length=MAX_GROUPS)] = [],  # noqa: B006
    session: SessionArg = "",
) -> ObserveResult:
    """Name a pending frame's segments: labelled ones become instances, groups regions;
    unlisted ones are ignored."""
    state = call.state
    target = session_of(call, session)
    store = pending_frames(state)

    def run() -> ObserveResult:
        with locked(target) as glmap:
            pending = store.get(target.handle, frame, glmap)
            named = [sid for e in labels if e.label.strip().lower() != IGNORE for sid in e.segments]
            semantics = semantics_from_labels(
                pending.segments(named),
                [SegmentLabel(tuple(e.segments), e.label, e.description) for e in labels],
                [SegmentGroup(tuple(g.members), g.description) for g in groups],
            )
            if semantics.objects:
                covered = semantics.objects[0].mask.copy()
                for obj in semantics.objects[1:]:
                    covered |= obj.mask
                report = glmap.integrate(
                    pending.masked_frame(covered), semantics, pending.frame_index
                )
                summary = report.summary()
            else:
                report = UpdateReport(frame_index=pending.frame_index)
                summary = "every segment ignored: nothing added"
            store.remove(target.handle, frame)
            name = target.live.name
        return ObserveResult(session=target.handle, map_name=name, summary=summary, report=report)

    return await in_thread(run)


TOOLS = [
    ToolSpec(label_segments, ADDS),
]
