"""Text buffers (`append_text`) and the extractive text merger."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import HashingEmbedder, default_embedder
from glmap_tools.language.text_merger import (
    DELIMITER,
    ExtractiveTextMerger,
    TextMerger,
    append_text,
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
