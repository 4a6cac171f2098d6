"""`LLMTextMerger`: the paper's text merger — an LLM rewrites a text buffer past 300 words.

Paper §3.1: "When the continuously concatenated text exceeds a predefined length threshold,
a lightweight LLM is invoked to merge the sentences" (Qwen3-8B in the paper). The reply is
validated (JSON with one description, within the word budget; one corrective retry).
Failures raise `LLMError`, and since fusion plans a frame before changing anything, the map
and its file stay as they were.
"""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import BaseModel, Field

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.llm import LLMClient, chat_structured
from glmap_tools.language.prompts import PromptSet, default_prompts
from glmap_tools.language.text_merger import DELIMITER, split_buffer, word_count


class MergedDescription(BaseModel):
    description: str = Field(min_length=1, description="the merged description")


class LLMTextMerger:
    """`TextMerger` backed by a chat model.

    Args:
        client: the model (e.g. `OllamaClient("qwen3:8b")`).
        prompts: prompt set; uses `text_merge`.
        kind: what the buffers describe, as the prompt words it ("object" or "area").
    """

    def __init__(
        self, client: LLMClient, prompts: PromptSet | None = None, kind: str = "object"
    ) -> None:
        self.client = client
        self.prompts = prompts or default_prompts()
        self.kind = kind
        self.calls = 0

    def merge(self, texts: Sequence[str], max_words: int) -> str:
        """Merge descriptions (or buffers) into one description of at most `max_words` words.

        Raises:
            InvalidInputError: max_words < 1 or `texts` is a str.
            LLMError: the model failed or kept exceeding the budget.
        """
        if not (isinstance(max_words, int) and max_words >= 1):
            raise InvalidInputError(f"max_words={max_words!r} must be an integer >= 1.")
        if isinstance(texts, str):
            raise InvalidInputError("merge() takes a sequence of descriptions, not one str.")
        descriptions = [d for t in texts for d in split_buffer(t)]
        if not descriptions:
            return ""
        if len(descriptions) == 1 and word_count(descriptions[0]) <= max_words:
            return descriptions[0]
        prompt = self.prompts.get("text_merge")
        content = prompt.format(
            kind=self.kind,
            max_words=max_words,
            descriptions="\n".join(f"- {d}" for d in descriptions),
        )

        def check(reply: MergedDescription) -> None:
            n = word_count(reply.description)
            if n > max_words:
                raise ValueError(f"the description has {n} words; the limit is {max_words}")
            if DELIMITER.strip() in reply.description:
                raise ValueError("write one description without '|' separators")

        self.calls += 1
        value, _ = chat_structured(
            self.client,
            [{"role": "user", "content": content}],
            MergedDescription,
            prompt=prompt,
            check=check,
        )
        return " ".join(value.description.split())
