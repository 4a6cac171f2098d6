"""Language: text embedders phi, the calibrated threshold tau_s, text-buffer mergers."""

from glmap_tools.language.embed import (
    Embedder,
    HashingEmbedder,
    MiniLMEmbedder,
    cosine_similarity,
    default_embedder,
)

__all__ = [
    "Embedder",
    "HashingEmbedder",
    "MiniLMEmbedder",
    "cosine_similarity",
    "default_embedder",
]
