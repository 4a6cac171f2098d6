"""The situation read by an LLM into the same form as the offline reader's.

The `sqa_situation` prompt asks the model for the reading (anchor, relation, posture or
activity, facing, side / clock constraints) beside the unit scores `LLMScorer(mode="sqa")`
reads, so one prompt serves both. `llm_read_situation` asks it with no units to score and
returns a `SituationReading` that `situate(..., reading=...)` takes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Literal

from pydantic import BaseModel, Field

from glmap_tools.language.llm import chat_structured
from glmap_tools.language.llm_scorer import SQA_QUESTIONS, _unit_lines
from glmap_tools.language.prompts import default_prompts
from glmap_tools.sqa.reading import Constraint, SituationReading

if TYPE_CHECKING:
    from glmap_tools.language.llm import LLMClient
    from glmap_tools.language.llm_scorer import UnitLike
    from glmap_tools.language.prompts import PromptSet

NO_UNITS = "There is nothing to score here: give an empty scores list."


class ConstraintReply(BaseModel):
    object: str = Field(min_length=1)
    side: Literal["left", "right", "behind", "front"] | None = None
    clock: int | None = Field(None, ge=1, le=12)


class ReadingReply(BaseModel):
    anchor: str = ""
    relation: str = ""
    posture: str | None = None
    activity: str | None = None
    near: list[str] = Field(default_factory=list)
    facing: str | None = None
    constraints: list[ConstraintReply] = Field(default_factory=list)


class UnitProbability(BaseModel):
    id: int
    probability: float = Field(ge=0.0, le=1.0)


class SituationReply(BaseModel):
    reading: ReadingReply
    scores: list[UnitProbability] = Field(default_factory=list)


def llm_read_situation(
    client: LLMClient,
    situation: str,
    units: Sequence[UnitLike] = (),
    prompts: PromptSet | None = None,
) -> SituationReading:
    """The model's reading of `situation` (prompt `sqa_situation`).

    Args:
        client: the chat model.
        situation: the situation text.
        units: instances to list for context (none: the reading alone is asked for).
        prompts: prompt set (a `--prompts DIR` override or the defaults).

    Raises:
        LLMError: the model failed or never gave a valid reading (`chat_structured`).
        InvalidInputError: a constraint with neither or both of side and clock.
    """

    prompt = (prompts or default_prompts()).get("sqa_situation")
    text = prompt.format(
        situation=situation,
        kind_plural="objects",
        question=SQA_QUESTIONS["instance"] if units else NO_UNITS,
        units=_unit_lines(units) if units else "(none)",
    )
    value, _ = chat_structured(
        client, [{"role": "user", "content": text}], SituationReply, prompt=prompt
    )
    r = value.reading
    return SituationReading(
        anchor=r.anchor.strip(),
        relation=r.relation.strip(),
        posture=r.posture,
        activity=r.activity,
        near=tuple(r.near),
        facing=r.facing.strip() if r.facing and r.facing.strip() else None,
        constraints=tuple(Constraint(c.object, c.side, c.clock) for c in r.constraints),
    )
