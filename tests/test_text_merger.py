"""Text buffers (`append_text`) and the extractive text merger."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.minilm import default_embedder
from glmap_tools.language.text_merger import (
    DELIMITER,
    FOLD_WORDS,
    MAX_UNITS_PER_DESCRIPTION,
    ExtractiveTextMerger,
    TextMerger,
    append_text,
    lazy_greedy,
    plain_greedy,
    split_buffer,
    word_count,
)

SOFA_VIEWS = [
    "a grey sofa with cushions",
    "A grey sofa with cushions.",
    "a gray sofa with cushions",
    "a grey fabric three-seat sofa with cushions",
    "the sofa is made of soft linen",
    "grey sofa with wooden legs",
    "a large grey upholstered sofa against the wall",
]


@pytest.fixture
def merger() -> ExtractiveTextMerger:
    return ExtractiveTextMerger(HashingEmbedder())


def _sentences(texts: list[str]) -> set[str]:
    return {" ".join(s.split()) for t in texts for s in split_buffer(t)}


# ------------------------------------------------------------------ buffers


def test_append_text_joins_descriptions_with_the_delimiter() -> None:
    buffer = append_text(append_text("", "a grey sofa"), "  a fabric couch ")
    assert buffer == "a grey sofa" + DELIMITER + "a fabric couch"
    assert split_buffer(buffer) == ["a grey sofa", "a fabric couch"]


def test_append_text_skips_an_exact_duplicate_and_empty_text() -> None:
    buffer = "a grey sofa" + DELIMITER + "a fabric couch"
    assert append_text(buffer, "a fabric couch") == buffer
    assert append_text(buffer, "   ") == buffer
    assert append_text(buffer, "a Fabric couch") != buffer  # only exact repeats are skipped


# ------------------------------------------------------------------ merger


def test_the_extractive_merger_satisfies_the_protocol(merger: ExtractiveTextMerger) -> None:
    assert isinstance(merger, TextMerger)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_merged_buffers_stay_under_every_word_limit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    vocab = ["grey", "brown", "wooden", "leather", "fabric", "sofa", "chair", "table", "lamp"]
    descriptions = [
        " ".join(rng.choice(vocab, size=int(rng.integers(1, 25))))
        + ("." if rng.random() < 0.5 else "")
        for _ in range(int(rng.integers(5, 40)))
    ]
    merger = ExtractiveTextMerger(HashingEmbedder(dim=128))
    for max_words in (1, 2, 3, 7, 20, 60, 300):
        out = merger.merge(descriptions, max_words)
        assert 1 <= word_count(out) <= max_words


def test_a_merged_buffer_keeps_attributes_from_different_descriptions(
    merger: ExtractiveTextMerger,
) -> None:
    out = merger.merge(SOFA_VIEWS * 5, max_words=40)  # about 200 words in
    assert word_count(out) <= 40
    for attribute in ("grey", "fabric", "linen", "wooden", "large"):
        assert attribute in out.lower(), attribute


def test_a_merged_buffer_only_holds_sentences_from_its_input(
    merger: ExtractiveTextMerger,
) -> None:
    out = merger.merge(SOFA_VIEWS, max_words=25)
    assert split_buffer(out)
    assert _sentences([out]) <= _sentences(SOFA_VIEWS)


def test_repeats_in_other_case_punctuation_or_spelling_are_dropped(
    merger: ExtractiveTextMerger,
) -> None:
    out = merger.merge(SOFA_VIEWS[:3] * 4, max_words=300)
    assert len(split_buffer(out)) == 1 and word_count(out) == 5


def test_minilm_folds_synonym_paraphrases_into_one_description() -> None:
    views = ["a grey sofa with cushions", "a gray couch with cushions", "grey couch, cushions"]
    out = ExtractiveTextMerger(default_embedder()).merge(views * 3, max_words=300)
    assert len(split_buffer(out)) == 1, out


def test_merging_is_deterministic(merger: ExtractiveTextMerger) -> None:
    first = merger.merge(SOFA_VIEWS * 3, max_words=30)
    assert merger.merge(SOFA_VIEWS * 3, max_words=30) == first
    assert ExtractiveTextMerger(HashingEmbedder()).merge(SOFA_VIEWS * 3, 30) == first


def test_an_empty_buffer_merges_to_an_empty_string(merger: ExtractiveTextMerger) -> None:
    assert merger.merge([], 300) == ""
    assert merger.merge(["", "   ", DELIMITER], 300) == ""


def test_a_single_huge_description_is_cut_at_a_word_boundary(
    merger: ExtractiveTextMerger,
) -> None:
    huge = " ".join(f"word{i}" for i in range(500))
    out = merger.merge([huge], 300)
    assert out == " ".join(f"word{i}" for i in range(300))


def test_a_huge_description_among_short_ones_does_not_break_the_limit(
    merger: ExtractiveTextMerger,
) -> None:
    huge = "a grey sofa " + " ".join(f"detail{i}" for i in range(400))
    out = merger.merge([huge, "a grey sofa", "a sofa of grey linen"], 300)
    assert word_count(out) <= 300 and "linen" in out


def test_a_whole_buffer_passed_as_one_text_is_split_into_its_descriptions(
    merger: ExtractiveTextMerger,
) -> None:
    buffer = DELIMITER.join(SOFA_VIEWS)
    assert merger.merge([buffer], 30) == merger.merge(SOFA_VIEWS, 30)


def test_bad_arguments_are_rejected_with_the_fix(merger: ExtractiveTextMerger) -> None:
    with pytest.raises(InvalidInputError, match="max_words=0"):
        merger.merge(["a sofa"], 0)
    with pytest.raises(InvalidInputError, match="split_buffer"):
        merger.merge("a sofa", 10)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="synonym_threshold=1.5"):
        ExtractiveTextMerger(HashingEmbedder(), synonym_threshold=1.5)


# ------------------------------------------------------------------ bounded work


class CountingEmbedder:
    """The hashing embedder, recording every text it is asked to embed."""

    def __init__(self) -> None:
        self.inner = HashingEmbedder()
        self.name, self.dim, self.default_tau_s = "counting", self.inner.dim, 0.44
        self.texts: list[str] = []

    def embed(self, texts):  # type: ignore[no-untyped-def]
        self.texts.extend(texts)
        return self.inner.embed(texts)


def _content_words_of(text: str) -> list[str]:
    return [
        w for w in ExtractiveTextMerger(HashingEmbedder()).texts_to_embed([text]) if " " not in w
    ]


def _made_up_sentences(seed: int, sentences: int) -> str:
    """`sentences` short sentences of distinct made-up words (nothing folds, nothing repeats)."""
    rng = np.random.default_rng(seed)
    return " ".join(
        " ".join(f"zq{int(w)}x" for w in rng.integers(0, 10**6, size=3)) + "."
        for _ in range(sentences)
    )


def test_a_merge_embeds_a_bounded_number_of_texts_however_long_its_buffer() -> None:
    counting = CountingEmbedder()
    merger = ExtractiveTextMerger(counting)
    descriptions = [_made_up_sentences(seed, 250) for seed in range(2)]  # 2 x 1000 words
    out = merger.merge(descriptions, 300)
    assert 1 <= word_count(out) <= 300
    # Units: at most MAX_UNITS_PER_DESCRIPTION per description; words: at most FOLD_WORDS.
    assert len(counting.texts) <= 2 * MAX_UNITS_PER_DESCRIPTION + FOLD_WORDS


def test_a_merge_keeps_sentences_only_from_the_first_eight_of_each_description(
    merger: ExtractiveTextMerger,
) -> None:
    description = _made_up_sentences(0, 40)
    first = description.split(". ")[:MAX_UNITS_PER_DESCRIPTION]
    out = merger.merge([description, "a grey sofa."], 300)
    kept = {s.rstrip(".") for part in split_buffer(out) for s in part.split(". ")}
    assert kept == {s.rstrip(".") for s in first} | {"a grey sofa"}
    # Split again, the merged buffer gives the same units: nothing new to embed.
    again = merger.texts_to_embed([out])
    assert set(again) <= set(merger.texts_to_embed([description, "a grey sofa."])) | set(
        _content_words_of(out)
    )


def test_texts_to_embed_are_exactly_what_the_merge_embeds() -> None:
    counting = CountingEmbedder()
    merger = ExtractiveTextMerger(counting)
    texts = SOFA_VIEWS + [_made_up_sentences(1, 30)]
    expected = merger.texts_to_embed(texts)
    merger.merge(texts, 40)
    assert counting.texts == expected


@pytest.mark.parametrize("seed", range(6))
def test_the_lazy_greedy_picks_what_the_plain_greedy_reference_picks(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 60))
    concepts = [set(rng.integers(0, 40, size=int(rng.integers(1, 8))).tolist()) for _ in range(n)]
    weight = {c: int(rng.integers(1, 5)) for c in range(40)}
    costs = rng.integers(2, 30, size=n).tolist()
    centrality = rng.uniform(-1, 1, size=n)
    scale = [max(0.05, (1.0 + float(c)) / 2.0) for c in centrality]
    for budget in (5, 40, 150, 1000):
        lazy = lazy_greedy(concepts, weight, costs, scale, centrality, budget)
        plain = plain_greedy(concepts, weight, costs, scale, centrality, budget)
        assert lazy == plain
