"""locate_situation: where a situation text puts the agent, with the views an MLLM answers from.

No `from __future__ import annotations` here: the SDK reads these signatures at runtime.
"""

from typing import Annotated, Any, Literal

from mcp.server.mcpserver import Context
from pydantic import BaseModel, Field

from glmap_tools.server.inputs import SessionArg
from glmap_tools.server.results import ImageResult, Picture
from glmap_tools.server.runtime import READ_ONLY, ToolSpec, in_thread, session_of
from glmap_tools.server.state import locked
from glmap_tools.views.common import encode_png

MAX_SITUATION = 512


class ConstraintIn(BaseModel):
    """An object at an egocentric side or clock hour."""

    object: str = Field(min_length=1, max_length=120, description="its words, e.g. 'lamp'")
    side: Literal["left", "right", "behind", "front"] | None = Field(
        None, description="where it is from me; or give clock"
    )
    clock: int | None = Field(
        None, ge=1, le=12, description="clock hour: 12 straight ahead, 3 right, 9 left"
    )


class ReadingIn(BaseModel):
    """A situation already read: where I am, what I face, what is around me."""

    anchor: str = Field("", max_length=200, description="object I am at ('' if none)")
    relation: str = Field("", max_length=40, description="at, on, in front of, next to, ...")
    posture: str | None = Field(None, max_length=40, description="standing, sitting, ...")
    activity: str | None = Field(None, max_length=120, description="what I am doing")
    near: list[str] = Field(default_factory=list, max_length=4, description="other objects")
    facing: str | None = Field(None, max_length=200, description="object I face")
    constraints: list[ConstraintIn] = Field(default_factory=list, max_length=8)


def locate(
    glmap: Any,
    situation: str,
    question: str = "",
    topdown: bool = False,
    reading: dict[str, Any] | None = None,
) -> tuple[dict[str, Any], list[bytes]]:
    """The situated pose and evidence as JSON, and PNGs: the heat map, the four views and,
    with `topdown`, a top-down crop around the pose with instance ids as markers.

    Args:
        glmap: the map.
        situation: the situation text T_l.
        question: optional T_q; when given, the offline map answer is included (with
            `supported=false` and the reason for questions the map alone cannot answer).
        topdown: add the GPT4Scene-style crop (`glmap_tools.sqa.views.topdown_crop`).
        reading: the situation already read (`SituationReading.as_dict` form); used
            instead of the offline reader's, and `situation` may then be empty.
    """
    from glmap_tools.sqa import situate
    from glmap_tools.sqa.answer import answer_at
    from glmap_tools.sqa.reading import SituationReading
    from glmap_tools.sqa.surroundings import surroundings
    from glmap_tools.sqa.views import heat_image, labelled_views, topdown_crop, views_sheet

    s = situate(glmap, situation, reading=SituationReading.from_dict(reading) if reading else None)
    views = labelled_views(glmap, s.x, s.y, s.heading)
    where = surroundings(glmap, s.x, s.y, s.heading)
    info: dict[str, Any] = {"situation": s.as_dict(), "around": where.as_dict(max_units=12)}
    info["views"] = [[v.direction, round(v.heading_deg)] for v in views]
    if question.strip():
        a, _ = answer_at(glmap, s, question, where=where)
        info["map_answer"] = {
            "answer": a.answer,
            "type": a.question_type,
            "supported": a.supported,
            "evidence": a.evidence,
        }
    images = [encode_png(heat_image(glmap, s, 384)), encode_png(views_sheet(views))]
    if topdown:
        images.append(encode_png(topdown_crop(glmap, s.x, s.y, s.heading).rgb))
    return info, images


async def locate_situation(
    ctx: Context,
    situation: Annotated[
        str,
        Field(
            max_length=MAX_SITUATION,
            description="where you are, e.g. 'sitting on the bed, facing the window'",
        ),
    ] = "",
    question: Annotated[str, Field(max_length=MAX_SITUATION)] = "",
    topdown: bool = False,
    reading: Annotated[
        ReadingIn | None,
        Field(description="your own reading of the situation (replaces the text's)"),
    ] = None,
    session: SessionArg = "",
) -> ImageResult:
    """Situated QA: locate a situation (text, or a reading: anchor, facing, objects on
    my left/right/behind or at a clock hour) in the map: pose, confidence, units around
    (distance, bearing), a heat map and 4 views (topdown: + a map crop with unit ids);
    situation.reading is how it was read (correct it and pass it back as reading);
    map_answer answers the question."""
    from glmap_tools.errors import InvalidInputError

    if not situation.strip() and reading is None:
        raise InvalidInputError(
            "give the situation text (e.g. 'sitting on the bed, facing the window') or a "
            "reading ({'anchor': 'bed', 'facing': 'window'})."
        )
    target = session_of(ctx, session)
    read = reading.model_dump() if reading is not None else None

    def run() -> ImageResult:
        with locked(target) as glmap:
            info, images = locate(glmap, situation, question, topdown, read)
        sit = info["situation"]
        note = (
            f"At ({sit['x']}, {sit['y']}) facing {sit['heading_deg']} deg"
            f"{' (low confidence)' if sit['low_confidence'] else ''}. "
            "Images: heat map, then views front|left / back|right"
            + (", then a top-down crop (ids = units, red arrow = you)." if topdown else ".")
        )
        return ImageResult(
            data=info, notes=[note], images=[Picture(format="png", data=png) for png in images]
        )

    return await in_thread(run)


TOOLS = [
    ToolSpec(locate_situation, READ_ONLY),
]
