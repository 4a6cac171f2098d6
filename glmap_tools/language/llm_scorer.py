"""LLM-backed scoring of semantic units: f_S for navigation and f_LLM for situated QA.

Paper §3.2: s_u = f_S(u, T_g) can be "prompting an LLM to estimate the similarity value
between T_g and observed instance T_o and region T_r"; for SQA, p_r = f_LLM(r, T_l) and
p_o = f_LLM(o, T_l). `LLMScorer` asks for a probability per unit, batches units per call,
validates every answer (one entry per id, probabilities in [0, 1], one corrective retry),
and caches by (prompt, goal, unit text), so re-scoring an unchanged map costs no calls.
It satisfies `glmap_tools.nav.Scorer`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from pydantic import BaseModel, Field

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.llm import LLMClient, chat_structured
from glmap_tools.language.prompts import PromptSet, default_prompts

MAX_UNIT_CHARS = 600  # characters of a unit's text shown to the model


class UnitLike(Protocol):
    unit_id: int
    kind: str
    text: str


@dataclass
class _Shown:
    """A unit as the prompt shows it (the id it is named by there)."""

    unit_id: int
    kind: str
    text: str


class UnitScore(BaseModel):
    id: int = Field(description="the unit id")
    probability: float = Field(ge=0.0, le=1.0, description="probability in [0, 1]")


class UnitScores(BaseModel):
    scores: list[UnitScore]


NAV_PROMPTS = {"instance": "unit_value_instance", "region": "unit_value_region"}
SQA_QUESTIONS = {
    "instance": "For each object, estimate the probability that the person is facing it.",
    "region": "For each area, estimate the probability that the person is in it or next to it.",
}


def _unit_lines(units: Sequence[UnitLike]) -> str:
    lines = []
    for u in units:
        text = " ".join(u.text.split())
        if len(text) > MAX_UNIT_CHARS:
            text = text[:MAX_UNIT_CHARS] + "..."
        lines.append(f"{u.unit_id}: {text}")
    return "\n".join(lines)


class LLMScorer:
    """Scores units with an LLM, batched and cached.

    Args:
        client: the chat model (e.g. `OllamaClient("qwen3:8b")`).
        prompts: prompt set (a `--prompts DIR` override or the defaults).
        batch_size: units per call.
        mode: "nav" (f_S for a goal: prompts unit_value_instance / unit_value_region) or
            "sqa" (f_LLM for a situation: prompt sqa_situation).
    """

    def __init__(
        self,
        client: LLMClient,
        prompts: PromptSet | None = None,
        *,
        batch_size: int = 16,
        mode: str = "nav",
    ) -> None:
        if not 1 <= batch_size <= 100:
            raise InvalidInputError(f"batch_size={batch_size} must be in 1..100.")
        if mode not in ("nav", "sqa"):
            raise InvalidInputError(f"mode={mode!r}; use 'nav' or 'sqa'.")
        self.client = client
        self.prompts = prompts or default_prompts()
        self.batch_size = batch_size
        self.mode = mode
        self.cache: dict[tuple[str, str, str, str], float] = {}
        self.calls = 0

    def _messages(self, goal: str, kind: str, batch: Sequence[UnitLike]) -> tuple[Any, list]:
        if self.mode == "nav":
            prompt = self.prompts.get(NAV_PROMPTS[kind])
            text = prompt.format(goal=goal, units=_unit_lines(batch))
        else:
            prompt = self.prompts.get("sqa_situation")
            text = prompt.format(
                situation=goal,
                kind_plural="objects" if kind == "instance" else "areas",
                question=SQA_QUESTIONS[kind],
                units=_unit_lines(batch),
            )
        return prompt, [{"role": "user", "content": text}]

    def _score_batch(self, goal: str, kind: str, batch: Sequence[UnitLike]) -> dict[int, float]:
        prompt, messages = self._messages(goal, kind, batch)
        wanted = {int(u.unit_id) for u in batch}

        def check(reply: UnitScores) -> None:
            got = [s.id for s in reply.scores]
            missing = sorted(wanted - set(got))
            unknown = sorted(set(got) - wanted)
            if missing or unknown or len(got) != len(set(got)):
                raise ValueError(
                    f"give exactly one score per id {sorted(wanted)}; missing {missing}, "
                    f"unknown {unknown}"
                )

        self.calls += 1
        value, _ = chat_structured(self.client, messages, UnitScores, prompt=prompt, check=check)
        return {s.id: s.probability for s in value.scores}

    def score(self, goal: str, units: Sequence[UnitLike]) -> np.ndarray:
        """[N] probabilities in [0, 1] of `units` for `goal` (a goal or a situation text).

        Raises:
            InvalidInputError: an empty goal or an unknown unit kind.
            LLMError: the model failed (see `chat_structured`); nothing is cached then.
        """
        goal = " ".join(str(goal).split())
        if not goal:
            raise InvalidInputError("goal is empty; describe what to find or the situation.")
        out = np.zeros(len(units), dtype=np.float64)
        todo: dict[str, list[tuple[int, UnitLike]]] = {"instance": [], "region": []}
        for i, u in enumerate(units):
            if u.kind not in todo:
                raise InvalidInputError(f"unit {u.unit_id} has kind {u.kind!r}.")
            key = (self.mode, goal, u.kind, u.text)
            if key in self.cache:
                out[i] = self.cache[key]
            else:
                todo[u.kind].append((i, u))
        for kind, pending in todo.items():
            # One score per distinct text (the cache's key). The prompt names each text by
            # its unit's id unless those collide or are negative (a frame's objects, scored
            # for the egocentric baseline, all carry -1): then by its place in the batch.
            own: dict[str, int] = {}
            for _, u in pending:
                own.setdefault(u.text, int(u.unit_id))
            texts = list(own)
            for start in range(0, len(texts), self.batch_size):
                chunk = texts[start : start + self.batch_size]
                ids = [own[t] for t in chunk]
                if len(set(ids)) < len(ids) or min(ids) < 0:
                    ids = list(range(1, len(chunk) + 1))
                shown = [_Shown(i, kind, t) for i, t in zip(ids, chunk, strict=True)]
                scores = self._score_batch(goal, kind, shown)
                for i, t in zip(ids, chunk, strict=True):
                    self.cache[(self.mode, goal, kind, t)] = float(scores[i])
            for i, u in pending:
                out[i] = self.cache[(self.mode, goal, kind, u.text)]
        return out
