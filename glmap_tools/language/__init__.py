"""Language: text embedders phi, the calibrated threshold tau_s, text-buffer mergers."""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.lazy import lazy_getattr

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder, HashingEmbedder, cosine_similarity
    from glmap_tools.language.minilm import MiniLMEmbedder, default_embedder

# Loaded on first use: the command lines (language.backends) need no numpy.
_LAZY = {
    **{
        name: "glmap_tools.language.embed"
        for name in ("Embedder", "HashingEmbedder", "cosine_similarity")
    },
    **{name: "glmap_tools.language.minilm" for name in ("MiniLMEmbedder", "default_embedder")},
}
__all__ = [
    "Embedder",
    "HashingEmbedder",
    "MiniLMEmbedder",
    "cosine_similarity",
    "default_embedder",
]
__getattr__ = lazy_getattr(__name__, _LAZY, globals())
