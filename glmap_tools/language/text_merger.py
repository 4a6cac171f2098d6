"""Text buffers T_o / T_r and the mergers that rewrite them once they grow too long.

A text buffer is the descriptions of one unit joined by `DELIMITER` ([T_j; T_i] in the
paper). Past a word limit (300 by default, the paper's buffer length) a `TextMerger`
rewrites it. `ExtractiveTextMerger` is the deterministic fallback used when no LLM is
configured: it keeps whole sentences of the buffer, never writes new words.
"""

from __future__ import annotations

import heapq
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import Embedder, cosine_similarity, normalise_rows

__all__ = [
    "DELIMITER",
    "MAX_DESCRIPTION_CHARS",
    "ExtractiveTextMerger",
    "TextMerger",
    "append_text",
    "split_buffer",
    "word_count",
]

DELIMITER = " | "
# The longest one description (or label) may be, in characters: enforced where descriptions
# enter the map (annotations, the MCP server), so one merge has a bounded input.
MAX_DESCRIPTION_CHARS = 1000
# Work bounds of the extractive merger (so a merge costs about linear in its buffer):
# sentences considered per description (later ones are left out of a merge), and content
# words embedded for synonym folding per merge (the most used; rarer words fold with none).
MAX_UNITS_PER_DESCRIPTION = 8
FOLD_WORDS = 64

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


def _sentences_of(description: str) -> list[str]:
    """The first MAX_UNITS_PER_DESCRIPTION sentences of a description, whitespace normalised."""
    sentences = (" ".join(s.split()) for s in _SENTENCE_END.split(description))
    return [s for s in sentences if s][:MAX_UNITS_PER_DESCRIPTION]


def _fold_vocabulary(units: Sequence[_Unit]) -> list[str]:
    """The FOLD_WORDS content words used by most units (ties: first seen), most used first."""
    df: dict[str, int] = {}
    for u in units:
        for w in u.content:
            df[w] = df.get(w, 0) + 1
    order = {w: i for i, w in enumerate(df)}
    return sorted(df, key=lambda w: (-df[w], order[w]))[:FOLD_WORDS]


def lazy_greedy(
    concepts: Sequence[set[int]],
    weight: dict[int, int],
    costs: Sequence[int],
    scale: Sequence[float],
    centrality: np.ndarray,
    budget: int,
) -> list[int]:
    """Budgeted max coverage, greedily by new concept weight per cost times `scale`.

    Lazy: a unit's score only falls as concepts get covered, so a stale score popped from
    the heap that is still the best once recomputed is the true best. O(concepts x log
    units); `plain_greedy` is the quadratic reference it equals.

    Args:
        concepts: concept ids per unit.
        weight: concept id -> weight.
        costs: [U] words each unit costs.
        scale: [U] score factor per unit.
        centrality: [U] tie-break, the more central unit first, then the earlier.
        budget: words available.

    Returns:
        Chosen unit indices, in the order they were picked.
    """
    covered: set[int] = set()

    def score(i: int) -> float:
        return sum(weight[c] for c in concepts[i] if c not in covered) / costs[i] * scale[i]

    heap = [(-score(i), -float(centrality[i]), i) for i in range(len(costs))]
    heapq.heapify(heap)
    chosen: list[int] = []
    while heap:
        stale, neg_central, i = heapq.heappop(heap)
        if costs[i] > budget or stale == 0.0:
            continue  # too long for what is left, or adds nothing: never again
        fresh = score(i)
        if fresh == 0.0:
            continue
        if heap and fresh < -heap[0][0] and not math.isclose(fresh, -heap[0][0]):
            heapq.heappush(heap, (-fresh, neg_central, i))
            continue
        chosen.append(i)
        covered |= concepts[i]
        budget -= costs[i]
    return chosen


def plain_greedy(
    concepts: Sequence[set[int]],
    weight: dict[int, int],
    costs: Sequence[int],
    scale: Sequence[float],
    centrality: np.ndarray,
    budget: int,
) -> list[int]:
    """The slow reference of `lazy_greedy`: rescore every unit at every pick."""
    covered: set[int] = set()
    chosen: list[int] = []
    remaining = set(range(len(costs)))
    while True:
        best, best_score = -1, 0.0
        for i in sorted(remaining):
            gain = sum(weight[c] for c in concepts[i] - covered)
            if costs[i] > budget or gain == 0:
                continue
            value = gain / costs[i] * scale[i]
            tie = math.isclose(value, best_score) and centrality[i] > centrality[best]
            if best < 0 or (value > best_score and not math.isclose(value, best_score)) or tie:
                best, best_score = i, value
        if best < 0:
            return chosen
        chosen.append(best)
        covered |= concepts[best]
        budget -= costs[best]
        remaining.discard(best)


def _truncate(text: str, max_words: int) -> str:
    """The first `max_words` whitespace-separated words of `text` (cut at a word boundary)."""
    return " ".join(text.split()[:max_words])


class ExtractiveTextMerger:
    """Deterministic, LLM-free text merger: keeps the most informative distinct sentences.

    The buffer is split into its descriptions and those into sentences (units). Then:

    1. exact repeats (same words, case and punctuation aside) are dropped; a description
       contributes its first MAX_UNITS_PER_DESCRIPTION sentences;
    2. every unit and the FOLD_WORDS most used content words are embedded; those words
       whose embeddings are near-duplicates (cosine >= `synonym_threshold`: grey/gray,
       tv/television, sofa/couch with MiniLM) fold into one concept, weighted by how many
       units mention it (rarer words are concepts of their own);
    3. units are picked greedily (lazily, from a heap) by new concept weight per word
       (budgeted max coverage), scaled by their centrality (mean cosine to the other
       units), until no unit adds a new concept or none fits in `max_words`. A paraphrase
       that adds no new concept is dropped; an attribute mentioned once (a material, a
       colour) is kept if it fits;
    4. kept sentences are regrouped by description, descriptions ordered by centrality,
       and joined with `DELIMITER`. A lone unit longer than the budget is cut at a word
       boundary.

    The work is bounded: one embedding call of at most (units + FOLD_WORDS) texts, then
    O(concepts x log units) for the selection, so a merge costs about linear in the
    length of its buffer.

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

    def texts_to_embed(self, texts: Sequence[str]) -> list[str]:
        """The texts `merge(texts, ...)` embeds: its units (sentences), then fold words.

        Embedding these ahead of time, outside a map's lock, fills an embedder's cache so
        the merge itself runs on cached vectors (see `glmap_tools.server`).
        """
        units = self._units([d for t in texts for d in split_buffer(t)])
        return [u.text for u in units] + _fold_vocabulary(units)

    # ----------------------------------------------------------------- steps

    @staticmethod
    def _units(descriptions: Sequence[str]) -> list[_Unit]:
        """Sentences of the descriptions, exact repeats (by word sequence) dropped.

        Only the first MAX_UNITS_PER_DESCRIPTION sentences of a description are units
        (a bounded number per description, the same when a merged buffer is split again).
        """
        seen: set[tuple[str, ...]] = set()
        units = []
        for d, description in enumerate(descriptions):
            for k, sentence in enumerate(_sentences_of(description)):
                key = tuple(_WORD.findall(sentence.lower()))
                if not sentence or key in seen:
                    continue
                seen.add(key)
                units.append(_Unit(d, k, sentence, word_count(sentence), _content_words(sentence)))
        return units

    def _concepts(
        self, units: Sequence[_Unit], vocab: Sequence[str], word_vectors: np.ndarray
    ) -> list[set[int]]:
        """Concept ids per unit: fold words (`vocab`) merged into synonyms by cosine.

        Content words outside `vocab` (rarer than the FOLD_WORDS most used) are each
        their own concept. Concept ids of folded words are their leader's index in
        `vocab`; other words get ids from len(vocab) on.
        """
        sim = cosine_similarity(word_vectors, word_vectors) if len(vocab) else None  # [K, K]
        concept_of: dict[str, int] = {}
        leaders: list[int] = []
        for i, word in enumerate(vocab):  # vocab is ranked: most used first
            assert sim is not None
            row = sim[i, leaders] if leaders else np.zeros(0)
            hits = np.flatnonzero(row >= self.synonym_threshold)
            if len(hits):
                concept_of[word] = leaders[int(hits[0])]
            else:
                leaders.append(i)
                concept_of[word] = i
        out: list[set[int]] = []
        for u in units:
            ids = set()
            for w in u.content:
                c = concept_of.get(w)
                if c is None:
                    c = concept_of[w] = len(concept_of) + len(vocab)
                ids.add(c)
            out.append(ids)
        return out

    def _select(self, units: Sequence[_Unit], max_words: int) -> tuple[list[int], np.ndarray]:
        """Greedy budgeted max coverage of concepts; returns (chosen unit ids, centrality)."""
        vocab = _fold_vocabulary(units)
        # Two calls: one-word texts batched with long sentences would be padded to them.
        unit_vectors = normalise_rows(self.embedder.embed([u.text for u in units]))  # [U, D]
        word_vectors = self.embedder.embed(vocab) if vocab else np.zeros((0, 1), np.float32)
        # Mean cosine to the other units, from the sum of the unit vectors (linear in U).
        self_sim = np.einsum("ij,ij->i", unit_vectors, unit_vectors)  # [U]
        centrality = (unit_vectors @ unit_vectors.sum(axis=0) - self_sim) / (len(units) - 1)
        concepts = self._concepts(units, vocab, word_vectors)
        weight: dict[int, int] = {}
        for cs in concepts:
            for c in cs:
                weight[c] = weight.get(c, 0) + 1
        # Centrality in [-1, 1] scales the score by 0.05 .. 1: odd ones out rank last.
        scale = [max(0.05, (1.0 + float(c)) / 2.0) for c in centrality]

        costs = [u.words + 1 for u in units]  # one extra word for its delimiter
        chosen = lazy_greedy(concepts, weight, costs, scale, centrality, max_words + 1)
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
