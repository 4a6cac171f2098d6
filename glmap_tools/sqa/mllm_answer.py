"""The situated question answered by a vision model from locate_situation's views.

Paper §3.2: T_a = f_MLLM({(I_k, d_k)}, T_q). One structured call (prompt `sqa_answer`) with
the four captioned views as one 2x2 sheet, a top-down crop with unit ids (GPT4Scene-style)
or both, and the map's notes of what is around by direction. Used by the SQA agent
(`agents/sqa.py`, an Ollama model) and by `locate_situation` when the server is told to
answer with a model (`glmap-mcp --llm sampling`: the client's).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from glmap_tools.language.llm import LLMClient, chat_structured
from glmap_tools.language.prompts import PromptSet, default_prompts

VIEW_ORDER = (
    "a 2x2 sheet: front (top left), left (top right), back (bottom left), right (bottom right)"
)
CROP_TEXT = (
    "a top-down map crop 6 m across centred on you, north up: the red arrow is you and the "
    "way you face, the numbers are the ids in the notes"
)
# What the MLLM is shown (paper: the four views; GPT4Scene-style: a top-down crop with ids).
VIEW_MODES = {
    "four": VIEW_ORDER,
    "topdown": CROP_TEXT,
    "both": f"{VIEW_ORDER}; then {CROP_TEXT}",
}


class SituatedAnswer(BaseModel):
    answer: str = Field(description="one to three words")
    confidence: float = Field(ge=0.0, le=1.0)


def context_notes(info: dict[str, Any], ids: bool = False) -> str:
    """The text beside the views: what the map says is around, by direction, leaving out
    what a wall hides (with `ids`, each unit's id as the top-down crop marks it)."""
    rows = info.get("around", {}).get("nearby", [])
    hidden = set(info.get("around", {}).get("behind_walls", []))  # another room's
    by_dir: dict[str, list[str]] = {}
    for row in rows:  # named fields (locate_situation) or bare rows (Surroundings.as_dict)
        uid, label, dist, _, direction = row.values() if isinstance(row, dict) else row
        if uid in hidden:
            continue
        by_dir.setdefault(direction, []).append(
            f"{label} ({dist} m, id {uid})" if ids else f"{label} ({dist} m)"
        )
    parts = [f"{d}: {', '.join(v[:4])}" for d, v in by_dir.items()]
    return "Map notes (nearest first) - " + "; ".join(parts) + "." if parts else ""


def mllm_answer(
    llm: LLMClient,
    situation: str,
    question: str,
    info: dict[str, Any],
    views_png: bytes,
    prompts: PromptSet | None = None,
    crop_png: bytes | None = None,
    views: str = "four",
) -> SituatedAnswer:
    """T_a = f_MLLM({(I_k, d_k)}, T_q): one structured call with the views sheet, the
    top-down crop (`views='topdown'`) or both (`'both'`: the sheet, then the crop)."""
    if views not in VIEW_MODES:
        raise ValueError(f"views={views!r} is not one of {list(VIEW_MODES)}.")
    if views != "four" and crop_png is None:
        raise ValueError(f"views={views!r} needs the top-down crop (locate with topdown=True).")
    images = {"four": [views_png], "topdown": [crop_png], "both": [views_png, crop_png]}[views]
    prompt = (prompts or default_prompts()).get("sqa_answer")
    content = prompt.format(
        situation=situation,
        views=VIEW_MODES[views],
        context=context_notes(info, ids=views != "four"),
        question=question,
    )
    value, _ = chat_structured(
        llm,
        [{"role": "user", "content": content, "images": images}],
        SituatedAnswer,
        prompt=prompt,
    )
    return value
