"""Text buffers T_o / T_r and the mergers that rewrite them once they grow too long.

A text buffer is the descriptions of one unit joined by `DELIMITER` ([T_j; T_i] in the
paper). Past a word limit (300 by default, the paper's buffer length) a `TextMerger`
rewrites it. `ExtractiveTextMerger` is the deterministic fallback used when no LLM is
configured: it keeps whole sentences of the buffer, never writes new words.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import Embedder, cosine_similarity

__all__ = [
    "DELIMITER",
    "ExtractiveTextMerger",
    "TextMerger",
    "append_text",
    "split_buffer",
    "word_count",
]

DELIMITER = " | "

_SENTENCE_END = re.compile(r"(?<=[.!?;])\s+")
_WORD = re.compile(r"[a-z0-9]+(?:[-'][a-z0-9]+)*")
_STOPWORDS = frozenset(
    """a an the and or but of on in at to by for from with without into onto over under
    above below near next beside behind between its it it's is are was were be been this
    that these those there here some any one's which who what where has have had as also
    very quite rather slightly partly partially visible seen shown appears appear looks
    look view image photo scene frame's can may""".split()  # noqa: SIM905
)
_SPELLING = {"gray": "grey", "color": "colour", "colored": "coloured", "colorful": "colourful"}


def split_buffer(buffer: str) -> list[str]:
    """The descriptions of a text buffer, stripped, empty ones dropped."""
    return [part.strip() for part in buffer.split(DELIMITER) if part.strip()]


def append_text(buffer: str, text: str) -> str:
    """Concatenate `text` to a text buffer with `DELIMITER`; exact duplicates are skipped.

    Args:
        buffer: descriptions joined by `DELIMITER` (may be empty).
        text: one new description; surrounding whitespace is ignored.

    Returns:
        The new buffer (`buffer` itself when `text` is empty or already one of its parts).
    """
    text = text.strip()
    if not text:
        return buffer
    if not buffer.strip():
        return text
    if text in split_buffer(buffer):
        return buffer
    return buffer + DELIMITER + text


def word_count(text: str) -> int:
    """Words as `str.split` counts them (delimiter bars included): the buffer-length measure."""
    return len(text.split())


@runtime_checkable
class TextMerger(Protocol):
    """Rewrites the descriptions of one text buffer into a buffer of at most `max_words`."""

    def merge(self, texts: Sequence[str], max_words: int) -> str:
        """Merge `texts` (descriptions, or buffers) into one buffer of <= max_words words."""
        ...


@dataclass(frozen=True)
class _Unit:
    """One sentence of the buffer: where it came from, its words and content concepts."""

    description: int  # index of the description it belongs to
    order: int  # position within that description
    text: str
    words: int  # word_count(text)
    content: tuple[str, ...]  # normalised content words, first occurrence order


def _content_words(text: str) -> tuple[str, ...]:
    """Lower-cased, plural-stripped content words of `text`, stop words removed, unique."""
    out: dict[str, None] = {}
    for word in _WORD.findall(text.lower()):
        if word in _STOPWORDS:
            continue
        word = _SPELLING.get(word, word)
        if len(word) > 4 and word.endswith("ies"):
            word = word[:-3] + "y"
        elif len(word) > 3 and word.endswith("s") and not word.endswith(("ss", "us", "is")):
            word = word[:-1]
        out[word] = None
    return tuple(out)


def _truncate(text: str, max_words: int) -> str:
    """The first `max_words` whitespace-separated words of `text` (cut at a word boundary)."""
    return " ".join(text.split()[:max_words])


class ExtractiveTextMerger:
    """Deterministic, LLM-free text merger: keeps the most informative distinct sentences.

    The buffer is split into its descriptions and those into sentences (units). Then:

    1. exact repeats (same words, case and punctuation aside) are dropped;
    2. every unit and every distinct content word is embedded; content words whose
       embeddings are near-duplicates (cosine >= `synonym_threshold`: grey/gray, tv/
       television, sofa/couch with MiniLM) fold into one concept, weighted by how many
       units mention it;
    3. units are picked greedily by new concept weight per word (budgeted max coverage),
       scaled by their centrality (mean cosine to the other units), until no unit adds a
       new concept or none fits in `max_words`. A paraphrase that adds no new concept is
       dropped; an attribute mentioned once (a material, a colour) is kept if it fits;
    4. kept sentences are regrouped by description, descriptions ordered by centrality,
       and joined with `DELIMITER`. A lone unit longer than the budget is cut at a word
       boundary.

    Args:
        embedder: the text embedder phi (the map's own, so vectors come from its cache).
        synonym_threshold: word-embedding cosine at and above which two content words count
            as one concept. 0.85 suits MiniLM (sofa/couch 0.86, three/four 0.82, large/small
            0.79); with `HashingEmbedder` only identical words fold.
    """

    def __init__(self, embedder: Embedder, synonym_threshold: float = 0.85) -> None:
        if not (isinstance(synonym_threshold, int | float) and 0.0 < synonym_threshold <= 1.0):
            raise InvalidInputError(
                f"synonym_threshold={synonym_threshold!r} must be a cosine in (0, 1]."
            )
        self.embedder = embedder
        self.synonym_threshold = float(synonym_threshold)

    def merge(self, texts: Sequence[str], max_words: int) -> str:
        """Merge descriptions (or buffers) into one buffer of at most `max_words` words.

        Args:
            texts: descriptions; an item holding `DELIMITER` is split into its descriptions.
            max_words: the limit, counted as `word_count` counts (delimiter bars included).

        Returns:
            The merged buffer ('' when there is no text).

        Raises:
            InvalidInputError: max_words < 1, or `texts` is a str or holds a non-str.
        """
        if not (isinstance(max_words, int) and max_words >= 1):
            raise InvalidInputError(f"max_words={max_words!r} must be an integer >= 1.")
        if isinstance(texts, str):
            raise InvalidInputError(
                f"merge() takes a sequence of descriptions, got the str {texts[:40]!r}; "
                "pass split_buffer(buffer) or [buffer]."
            )
        for i, t in enumerate(texts):
            if not isinstance(t, str):
                raise InvalidInputError(f"texts[{i}] is a {type(t).__name__}, not a str.")
        descriptions = [d for t in texts for d in split_buffer(t)]
        units = self._units(descriptions)
        if not units:
            return ""
        if len(units) == 1:
            return _truncate(units[0].text, max_words)
        chosen, centrality = self._select(units, max_words)
        if not chosen:  # even the best unit is too long: keep its head
            best = max(range(len(units)), key=lambda i: (centrality[i], -i))
            return _truncate(units[best].text, max_words)
        return self._render(units, chosen, centrality, max_words)

    # ----------------------------------------------------------------- steps

    @staticmethod
    def _units(descriptions: Sequence[str]) -> list[_Unit]:
        """Sentences of the descriptions, exact repeats (by word sequence) dropped."""
        seen: set[tuple[str, ...]] = set()
        units = []
        for d, description in enumerate(descriptions):
            for k, sentence in enumerate(_SENTENCE_END.split(description)):
                sentence = " ".join(sentence.split())
                key = tuple(_WORD.findall(sentence.lower()))
                if not sentence or key in seen:
                    continue
                seen.add(key)
                units.append(_Unit(d, k, sentence, word_count(sentence), _content_words(sentence)))
        return units

    def _concepts(self, units: Sequence[_Unit], word_vectors: np.ndarray) -> list[set[int]]:
        """Concept ids per unit: content words folded into synonyms by embedding cosine."""
        vocab = list(dict.fromkeys(w for u in units for w in u.content))
        df = {w: sum(w in u.content for u in units) for w in vocab}
        # Leaders first by how many units use them, then by first appearance.
        ranked = sorted(range(len(vocab)), key=lambda i: (-df[vocab[i]], i))
        sim = cosine_similarity(word_vectors, word_vectors)  # [V, V]
        concept_of: dict[str, int] = {}
        leaders: list[int] = []
        for i in ranked:
            match = next((j for j in leaders if sim[i, j] >= self.synonym_threshold), None)
            if match is None:
                leaders.append(i)
                match = i
            concept_of[vocab[i]] = match
        return [{concept_of[w] for w in u.content} for u in units]

    def _select(self, units: Sequence[_Unit], max_words: int) -> tuple[list[int], np.ndarray]:
        """Greedy budgeted max coverage of concepts; returns (chosen unit ids, centrality)."""
        vocab = list(dict.fromkeys(w for u in units for w in u.content))
        vectors = self.embedder.embed([u.text for u in units] + vocab)
        unit_vectors, word_vectors = vectors[: len(units)], vectors[len(units) :]
        sim = cosine_similarity(unit_vectors, unit_vectors)  # [U, U]
        centrality = (sim.sum(axis=1) - np.diag(sim)) / (len(units) - 1)  # [U]
        concepts = self._concepts(units, word_vectors)
        weight: dict[int, int] = {}
        for cs in concepts:
            for c in cs:
                weight[c] = weight.get(c, 0) + 1

        covered: set[int] = set()
        chosen: list[int] = []
        budget = max_words + 1  # each unit is charged one extra word for its delimiter
        remaining = set(range(len(units)))
        while remaining:
            best, best_score = -1, 0.0
            for i in sorted(remaining):
                cost = units[i].words + 1
                gain = sum(weight[c] for c in concepts[i] - covered)
                if cost > budget or gain == 0:
                    continue
                # Centrality in [-1, 1] scales the score by 0.05 .. 1: odd ones out rank last.
                score = gain / cost * max(0.05, (1.0 + float(centrality[i])) / 2.0)
                better = best < 0 or score > best_score * (1 + 1e-9)
                tie_more_central = math.isclose(score, best_score) and (
                    centrality[i] > centrality[best]
                )
                if better or tie_more_central:
                    best, best_score = i, score
            if best < 0:
                break
            chosen.append(best)
            covered |= concepts[best]
            budget -= units[best].words + 1
            remaining.discard(best)
        return chosen, centrality

    @staticmethod
    def _render(
        units: Sequence[_Unit], chosen: Sequence[int], centrality: np.ndarray, max_words: int
    ) -> str:
        """Join the chosen units: by description, most central description first."""
        groups: dict[int, list[int]] = {}
        for i in chosen:
            groups.setdefault(units[i].description, []).append(i)
        rank = sorted(groups, key=lambda d: (-max(float(centrality[i]) for i in groups[d]), d))
        parts = [
            " ".join(units[i].text for i in sorted(groups[d], key=lambda i: units[i].order))
            for d in rank
        ]
        out = DELIMITER.join(parts)
        assert word_count(out) <= max_words, (word_count(out), max_words)
        return out
