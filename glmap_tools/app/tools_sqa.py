"""locate_situation: where a situation text puts the agent, with the views an MLLM answers from.

No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, Field

from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.results import ImageResult, Picture, Reply
from glmap_tools.app.runtime import READ_ONLY, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import locked
from glmap_tools.app.sim_results import SamplingReport, sampling_report
from glmap_tools.errors import InvalidInputError, LLMError
from glmap_tools.language.backends import LLMSettings
from glmap_tools.language.sampling import fallback_message, note_fallback
from glmap_tools.views.common import encode_png

if TYPE_CHECKING:
    from glmap_tools.map import GLMap

# Imports inside functions stay there: gaussians load on first use: the tools load before these do,
# in the server and the in-process toolset alike.

MAX_SITUATION = 512


class ConstraintIn(BaseModel):
    """An object at a side of me, or at a clock hour (12 ahead, 3 right)."""

    object: str = Field(min_length=1, max_length=120)
    side: Literal["left", "right", "behind", "front"] | None = None
    clock: int | None = Field(None, ge=1, le=12)


class ReadingIn(BaseModel):
    """A situation already read (other keys of situation.reading are ignored)."""

    anchor: str = Field("", max_length=200, description="the object I am at")
    relation: str = Field("", max_length=40, description="at, on, next to")
    facing: str | None = Field(None, max_length=200)
    constraints: list[ConstraintIn] = Field(default_factory=list, max_length=8)


# The fields of one nearby unit (`Nearby.as_row`): bearing from the heading, + = left.
NEARBY_FIELDS = ("id", "label", "distance_m", "bearing_deg", "direction")
ScoredText = tuple[int, str, float, str]  # [id, kind, score, text]


class ConstraintOut(Reply):
    """An object at a side of me or at a clock hour, as read."""

    object: str
    side: str | None = Field(description="left, right, behind or front")
    clock: int | None = Field(description="1..12: 12 ahead, 3 to the right")


class ReadingOut(Reply):
    """How the situation text was read (pass it back as `reading` to correct it)."""

    anchor: str = Field(description="the object or room I am at; '' when none is named")
    relation: str = Field(description="at, on, next to, ...")
    posture: str | None
    activity: str | None
    near: list[str] = Field(description="other objects the position names")
    facing: str | None = Field(description="the object I face")
    constraints: list[ConstraintOut]


class Situated(Reply):
    """Where the situation puts me, and on what evidence."""

    x: float = Field(description="metres")
    y: float = Field(description="metres")
    heading_deg: float = Field(description="counter-clockwise from +x")
    confidence: float
    low_confidence: bool
    location_text: str = Field(description="the phrase scored for the position")
    facing_text: str = Field(description="the phrase scored for the facing")
    anchors: list[ScoredText] = Field(description="[id, kind, score, text] of the anchor")
    facing: list[ScoredText] = Field(description="[id, kind, score, text] of what I face")
    notes: list[str]
    reading: ReadingOut | None


class NearbyUnit(Reply):
    """A unit near the pose."""

    id: int
    label: str
    distance_m: float
    bearing_deg: int = Field(description="from my heading, + = to my left")
    direction: str = Field(description="front, left, back or right")


class Around(Reply):
    """What is around the pose."""

    pose: tuple[float, float, int] = Field(description="x, y (m), heading (deg)")
    nearby: list[NearbyUnit] = Field(description="nearest first")
    regions: list[tuple[int, str, list[int]]] = Field(description="[id, text, member ids]")
    behind_walls: list[int] | None = Field(
        default=None, description="ids of nearby units a wall hides (another room)"
    )


class MapAnswer(Reply):
    """The map's own answer to the question."""

    answer: str
    type: str = Field(description="the question's family")
    supported: bool = Field(description="false: the map alone cannot answer it")
    evidence: str


class ModelAnswer(Reply):
    """The configured model's answer from the four views and the map's notes."""

    answer: str
    confidence: float
    by: str


class SituationResult(Reply):
    """locate_situation: the pose, what is around it, the views; answers when asked."""

    situation: Situated
    around: Around
    views: list[tuple[str, int]] = Field(description="[direction, heading (deg)] per view")
    map_answer: MapAnswer | None = Field(default=None, description="when a question is given")
    read_by: str | None = Field(default=None, description="the model that read the situation")
    model_answer: ModelAnswer | None = Field(default=None, description="when a model answers")
    llm: SamplingReport | None = Field(default=None, description="when the client's model ran")


def locate(
    glmap: "GLMap",
    situation: str,
    question: str = "",
    topdown: bool = False,
    reading: dict[str, Any] | None = None,
) -> tuple[SituationResult, list[bytes]]:
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
    around = where.as_dict(max_units=12)
    around["nearby"] = [dict(zip(NEARBY_FIELDS, row, strict=True)) for row in around["nearby"]]
    info = SituationResult(
        situation=Situated.model_validate(s.as_dict()),
        around=Around.model_validate(around),
        views=[(v.direction, round(v.heading_deg)) for v in views],
    )
    if question.strip():
        a, _ = answer_at(glmap, s, question, where=where)
        info.map_answer = MapAnswer(
            answer=a.answer, type=a.question_type, supported=a.supported, evidence=a.evidence
        )
    images = [encode_png(heat_image(glmap, s, 384)), encode_png(views_sheet(views))]
    if topdown:
        images.append(encode_png(topdown_crop(glmap, s.x, s.y, s.heading).rgb))
    return info, images


def model_reading(settings: "LLMSettings", situation: str) -> tuple[dict[str, Any] | None, str]:
    """The situation read by the configured model (`LLMSettings.reader`), or None for the
    offline reader; and who read it, for the result.

    A sampling reader that fails, is refused or times out falls back (`settings.fallback`:
    Ollama, else the offline reader; "none" raises) and says so in a log line.
    """
    from glmap_tools.sqa.llm_reading import llm_read_situation

    reader = settings.reader
    if reader == "rules" or not situation.strip():
        return None, "rules"
    if reader == "llm":
        reading = llm_read_situation(settings.client(), situation, prompts=settings.prompt_set())
        return reading.as_dict(), f"ollama {settings.model}"
    try:
        client = settings.sampling_client()
        reading = llm_read_situation(client, situation, prompts=settings.prompt_set())
        return reading.as_dict(), "the client's model (sampling)"
    except LLMError as exc:
        if settings.fallback == "none":
            raise
        if settings.fallback == "ollama":
            note_fallback(fallback_message("reading the situation", exc, "ollama"))
            ollama = LLMSettings(**{**vars(settings), "reader": "llm"})
            return model_reading(ollama, situation)
        note_fallback(fallback_message("reading the situation", exc, "the rule reader"))
        return None, "rules (fallback)"


def model_answer(
    settings: "LLMSettings", situation: str, question: str, info: dict[str, Any], views_png: bytes
) -> ModelAnswer | None:
    """The configured model's answer (`LLMSettings.answerer`) from the four views and the
    map's notes (glmap_tools.sqa.mllm_answer), or None when a sampling request failed and
    the map's answer stands (`settings.fallback`; "none" raises), said in a log line."""
    from glmap_tools.sqa.mllm_answer import mllm_answer

    by = "the client's model (sampling)" if settings.answerer == "sampling" else "ollama"
    backend = "sampling" if settings.answerer == "sampling" else "ollama"
    try:
        reply = mllm_answer(
            settings.vision_client(backend),
            situation,
            question,
            info,
            views_png,
            settings.prompt_set(),
        )
    except LLMError as exc:
        if settings.answerer != "sampling" or settings.fallback == "none":
            raise
        note_fallback(fallback_message("answering the question", exc, "the map's answer"))
        return None
    return ModelAnswer(answer=reply.answer, confidence=reply.confidence, by=by)


async def locate_situation(
    call: Call,
    situation: Annotated[
        str,
        Field(
            max_length=MAX_SITUATION,
            description="e.g. 'sitting on the bed, facing the window'",
        ),
    ] = "",
    question: Annotated[str, Field(max_length=MAX_SITUATION)] = "",
    topdown: bool = False,
    reading: ReadingIn | None = None,
    session: SessionArg = "",
) -> ImageResult[SituationResult]:
    """Situated QA: place a situation (text or reading) in the map: pose, nearby units, heat
    map, 4 views; situation.reading: how it was read (fix, pass back)."""

    if not situation.strip() and reading is None:
        raise InvalidInputError(
            "give the situation text (e.g. 'sitting on the bed, facing the window') or a "
            "reading ({'anchor': 'bed', 'facing': 'window'})."
        )
    target = session_of(call, session)
    read = reading.model_dump() if reading is not None else None
    read_by = "given" if read is not None else "rules"
    settings = call.state.config.llm
    if read is None and settings.reader != "rules":  # off the map's lock
        read, read_by = await in_thread(lambda: model_reading(settings, situation))

    def run() -> ImageResult[SituationResult]:
        with locked(target) as glmap:
            info, images = locate(glmap, situation, question, topdown, read)
        if read_by not in ("given", "rules"):
            info.read_by = read_by
        if question.strip() and settings.answerer != "map":  # the views are made: ask
            said = model_answer(settings, situation or str(read), question, info.given(), images[1])
            if said is not None:
                info.model_answer = said
        llm = sampling_report()  # the session's sampling: calls, tokens, fallbacks
        if llm is not None:
            info.llm = llm
        sit = info.situation
        note = (
            f"At ({sit.x}, {sit.y}) facing {sit.heading_deg} deg"
            f"{' (low confidence)' if sit.low_confidence else ''}. "
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
