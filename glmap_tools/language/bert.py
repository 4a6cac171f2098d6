"""A sentence-transformers BERT model (all-MiniLM-L6-v2) run with numpy from its own files.

The model folder a sentence-transformers model is saved in holds everything: `config.json`
(layers, heads, LayerNorm epsilon), `model.safetensors` (the weights), `tokenizer.json`
(the WordPiece tokenizer, read by the `tokenizers` library), `sentence_bert_config.json`
(the longest input) and `1_Pooling/config.json` (mean pooling). `BertSentenceEncoder`
computes what sentence-transformers computes — token, position and type embeddings,
LayerNorm, the encoder layers (self-attention, GELU feed-forward, each with a residual and a
LayerNorm), the mean over the tokens, L2 normalisation — without importing torch,
transformers or sentence-transformers, which take ~4 s to import. Its vectors equal
sentence-transformers' to float32 precision (tests/test_embed.py).

Texts are encoded in batches of equal token count, so there is no padding and no attention
mask, and each text of a batch goes through the layers on its own: its vector is the one it
gets alone, bit for bit, on any BLAS.

The dense layers of a short input (a search query: ~10 tokens) are computed in column panels
narrow enough for OpenBLAS's small-matrix kernel, which reads the weights in place instead of
packing them first (2-3x faster at 10 tokens), and every product is summed over blocks of 384
inputs in a fixed order, so a row's result does not depend on how many rows share the call
(`dense`). `encode_ids_reference` is the plain one-product-per-layer computation.
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import Any

import numba
import numpy as np

from glmap_tools.errors import GLMapError

# Imports inside functions stay there: safetensors, scipy, tokenizers load on first use; an import
# that may fail is caught where it is used.


def is_mean_pooled_bert(path: str | Path) -> bool:
    """Whether `path` holds a saved sentence-transformers BERT with mean pooling and
    safetensors weights (what `BertSentenceEncoder` reads)."""
    folder = Path(path)
    try:
        config = json.loads((folder / "config.json").read_text(encoding="utf-8"))
        pooling = json.loads((folder / "1_Pooling" / "config.json").read_text("utf-8"))
        modules = json.loads((folder / "modules.json").read_text("utf-8"))
    except (OSError, ValueError):
        return False
    objects = isinstance(config, dict) and isinstance(pooling, dict)
    if not (objects and isinstance(modules, list) and all(isinstance(m, dict) for m in modules)):
        return False  # not files sentence-transformers writes; it says what is wrong
    kinds = [str(m.get("type", "")).rsplit(".", 1)[-1] for m in modules]
    return (
        config.get("model_type") == "bert"
        and bool(pooling.get("pooling_mode_mean_tokens"))
        and kinds in (["Transformer", "Pooling", "Normalize"], ["Transformer", "Pooling"])
        and (folder / "model.safetensors").is_file()
        and (folder / "tokenizer.json").is_file()
    )


SMALL_GEMM_MNK = 1_000_000  # OpenBLAS's small-matrix kernel takes products of M*N*K <= this
K_BLOCK = 384  # inputs per partial product; partial products are summed in order
MIN_PANEL = 32  # narrower panels cost more in calls than the small kernel saves


def dense(x: np.ndarray, w: np.ndarray, bias: np.ndarray, panels: bool = True) -> np.ndarray:
    """`x @ w + bias` in float32, in small-kernel column panels when `x` has few rows.

    Args:
        x: [M, K] float32 inputs.
        w: [K, N] float32 weights (C order).
        bias: [N] float32.
        panels: split the columns into panels of M * width * K_BLOCK <= SMALL_GEMM_MNK
            (False: one product per input block, whatever M).

    Returns:
        [M, N] float32. Each output is the in-order sum over K_BLOCK-input blocks of
        products whose summation order BLAS does not change with M (checked at load by
        `panels_agree`), so a row's result is the same in a batch of one or of many.
    """
    m, k_total = x.shape
    n = w.shape[1]
    width = n
    fit = SMALL_GEMM_MNK // max(m * K_BLOCK, 1)
    if panels and fit >= MIN_PANEL:
        width = min(n, 1 << (fit.bit_length() - 1))
    out = np.empty((m, n), dtype=np.float32)
    part = np.empty((m, width), dtype=np.float32)
    for p0 in range(0, n, width):
        p1 = min(p0 + width, n)
        o = out[:, p0:p1]
        np.matmul(x[:, :K_BLOCK], w[:K_BLOCK, p0:p1], out=o)
        for k0 in range(K_BLOCK, k_total, K_BLOCK):
            t = part[:, : p1 - p0]
            np.matmul(x[:, k0 : k0 + K_BLOCK], w[k0 : k0 + K_BLOCK, p0:p1], out=t)
            o += t
    out += bias
    return out


def panels_agree(w: np.ndarray, seed: int = 0) -> bool:
    """Whether this BLAS gives a few rows computed in panels bit for bit the values it gives
    the same rows inside a large product (so `dense` may use panels).

    Args:
        w: [K, N] float32 weights to probe with, K <= K_BLOCK.
    """
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((512, w.shape[0])).astype(np.float32)
    bias = np.zeros(w.shape[1], dtype=np.float32)
    many = dense(x, w, bias, panels=True)
    # A text is at least 2 tokens ([CLS], [SEP]); a single row would go through gemv.
    return all(np.array_equal(dense(x[:m], w, bias, panels=True), many[:m]) for m in (2, 3, 10))


def _layer_norm(x: np.ndarray, weight: np.ndarray, bias: np.ndarray, eps: float) -> np.ndarray:
    mean = x.mean(axis=-1, keepdims=True)
    centred = x - mean
    var = (centred * centred).mean(axis=-1, keepdims=True)
    return centred / np.sqrt(var + eps) * weight + bias


def _gelu(x: np.ndarray) -> np.ndarray:
    """BERT's exact GELU, x * Phi(x)."""
    from scipy.special import erf

    return 0.5 * x * (1.0 + erf(x / math.sqrt(2.0)))


ERF_RANGE = 4.0  # past this erf rounds to +-1 in float32
ERF_DEGREE = 28  # Chebyshev degree of erf on [0, ERF_RANGE]: within 2e-14 of libm's erf
GELU_BLOCK = 64  # values whose erf series are summed together


@functools.cache
def _erf_coefficients() -> np.ndarray:
    """Chebyshev coefficients of erf on [0, ERF_RANGE] (mapped to [-1, 1])."""
    half = ERF_RANGE / 2.0
    return np.polynomial.chebyshev.chebinterpolate(
        np.vectorize(lambda t: math.erf(half + half * t)), ERF_DEGREE
    )


@numba.njit(cache=True)
def _gelu_kernel(x: np.ndarray, coefficients: np.ndarray, out: np.ndarray) -> None:
    """`_gelu` of the flat float32 `x` into `out`, erf by a Chebyshev series (no libm call;
    Clenshaw's recurrence runs across a block of values, so it vectorises); float32
    operations in `_gelu`'s order."""
    root2 = np.float32(math.sqrt(2.0))
    half = np.float32(0.5)
    one = np.float32(1.0)
    c_last = coefficients.shape[0] - 1
    scale = 2.0 / ERF_RANGE
    y = np.empty(GELU_BLOCK)
    b1 = np.empty(GELU_BLOCK)
    b2 = np.empty(GELU_BLOCK)
    for start in range(0, x.shape[0], GELU_BLOCK):
        m = min(GELU_BLOCK, x.shape[0] - start)
        for j in range(m):
            t = np.float64(x[start + j] / root2)
            y[j] = min(abs(t), ERF_RANGE) * scale - 1.0  # [-1, 1]
            b1[j] = 0.0
            b2[j] = 0.0
        for k in range(c_last, 0, -1):
            c = coefficients[k]
            for j in range(m):
                nxt = c + 2.0 * y[j] * b1[j] - b2[j]
                b2[j] = b1[j]
                b1[j] = nxt
        for j in range(m):
            v = x[start + j]
            t = np.float64(v / root2)
            e = np.float32(math.copysign(coefficients[0] + y[j] * b1[j] - b2[j], t))
            out[start + j] = half * v * (one + e)


def gelu(x: np.ndarray) -> np.ndarray:
    """BERT's exact GELU of float32 `x`, as `_gelu` computes it (to the last bit but for
    inputs whose erf lies within 2e-14 of a float32 rounding boundary)."""
    flat = np.ascontiguousarray(x, dtype=np.float32).reshape(-1)
    out = np.empty_like(flat)
    _gelu_kernel(flat, _erf_coefficients(), out)
    return out.reshape(x.shape)


class BertSentenceEncoder:
    """Mean-pooled, L2-normalised BERT sentence vectors from a saved model folder.

    Args:
        path: the folder of a saved sentence-transformers BERT model.

    Raises:
        GLMapError: a file is missing or the model is not a mean-pooled BERT.
    """

    def __init__(self, path: str | Path) -> None:
        folder = Path(path)
        try:
            from safetensors.numpy import load_file
            from tokenizers import Tokenizer

            config = json.loads((folder / "config.json").read_text(encoding="utf-8"))
            pooling = json.loads((folder / "1_Pooling" / "config.json").read_text("utf-8"))
            st_config = json.loads((folder / "sentence_bert_config.json").read_text("utf-8"))
            weights = load_file(str(folder / "model.safetensors"))
            self.tokenizer = Tokenizer.from_file(str(folder / "tokenizer.json"))
        except (OSError, ValueError, ImportError) as exc:
            raise GLMapError(f"cannot read the BERT model in {folder.name!r}: {exc}") from exc
        if not all(isinstance(c, dict) for c in (config, pooling, st_config)):
            raise GLMapError(
                f"the model in {folder.name!r} has a config file that is not a JSON object."
            )
        if config.get("model_type") != "bert" or not pooling.get("pooling_mode_mean_tokens"):
            raise GLMapError(
                f"the model in {folder.name!r} is not a mean-pooled BERT; load it with "
                "sentence-transformers instead."
            )
        try:
            self._read(config, st_config, weights)
        except (KeyError, TypeError, ValueError, OverflowError, IndexError) as exc:
            raise GLMapError(
                f"cannot read the BERT model in {folder.name!r}: {type(exc).__name__} {exc} in "
                "its configs or weights; re-save it with sentence-transformers."
            ) from None

    def _read(
        self, config: dict[str, Any], st_config: dict[str, Any], weights: dict[str, np.ndarray]
    ) -> None:
        """Sizes from the configs, weights by name (a missing key raises KeyError)."""
        self.max_length = int(st_config.get("max_seq_length", 256))
        if not 1 <= self.max_length <= 1_000_000:
            raise ValueError(f"max_seq_length {self.max_length} is not in 1..1000000")
        self.tokenizer.enable_truncation(self.max_length)
        self.tokenizer.no_padding()
        self.heads = int(config["num_attention_heads"])
        self.eps = float(config["layer_norm_eps"])
        self.dim = int(config["hidden_size"])
        prefix = "bert." if "bert.embeddings.word_embeddings.weight" in weights else ""
        w = {k[len(prefix) :]: np.ascontiguousarray(v) for k, v in weights.items()}
        self.word = w["embeddings.word_embeddings.weight"]
        if self.word.ndim != 2 or self.word.shape[1] != self.dim:
            raise ValueError(f"hidden_size {self.dim} is not the width of the word embeddings")
        if not (1 <= self.heads <= self.dim and self.dim % self.heads == 0):
            raise ValueError(f"num_attention_heads {self.heads} does not divide {self.dim}")
        if not (math.isfinite(self.eps) and self.eps > 0):
            raise ValueError(f"layer_norm_eps {self.eps} is not a positive number")
        self.position = w["embeddings.position_embeddings.weight"]
        self.token_type = w["embeddings.token_type_embeddings.weight"][0]
        self.embed_norm = (w["embeddings.LayerNorm.weight"], w["embeddings.LayerNorm.bias"])
        self.layers = []
        for i in range(int(config["num_hidden_layers"])):
            p = f"encoder.layer.{i}."
            qkv = np.concatenate(
                [w[p + f"attention.self.{n}.weight"] for n in ("query", "key", "value")]
            ).T.copy()  # [dim, 3 dim]
            qkv_bias = np.concatenate(
                [w[p + f"attention.self.{n}.bias"] for n in ("query", "key", "value")]
            )
            self.layers.append(
                (
                    qkv,
                    qkv_bias,
                    w[p + "attention.output.dense.weight"].T.copy(),
                    w[p + "attention.output.dense.bias"],
                    (
                        w[p + "attention.output.LayerNorm.weight"],
                        w[p + "attention.output.LayerNorm.bias"],
                    ),
                    w[p + "intermediate.dense.weight"].T.copy(),
                    w[p + "intermediate.dense.bias"],
                    w[p + "output.dense.weight"].T.copy(),
                    w[p + "output.dense.bias"],
                    (w[p + "output.LayerNorm.weight"], w[p + "output.LayerNorm.bias"]),
                )
            )
        self.panels = panels_agree(self.layers[0][0][:K_BLOCK])

    def token_ids(self, texts: list[str]) -> list[list[int]]:
        """The token ids of each text ([CLS] ... [SEP], at most `max_length`)."""
        return [e.ids for e in self.tokenizer.encode_batch(texts)]

    def encode_ids(self, ids: np.ndarray) -> np.ndarray:  # [B, L] -> [B, dim]
        """Sentence vectors of a batch of equal-length token id rows."""
        return self._encode(ids, self.panels)

    def encode_ids_reference(self, ids: np.ndarray) -> np.ndarray:  # [B, L] -> [B, dim]
        """`encode_ids` with one plain product per dense layer (for tests and benchmarks)."""
        return self._encode(ids, None)

    def _encode(self, ids: np.ndarray, panels: bool | None) -> np.ndarray:
        """The encoder; `panels` None: plain `x @ w + b` products, else `dense(..., panels)`."""

        def linear(x: np.ndarray, w: np.ndarray, bias: np.ndarray) -> np.ndarray:
            return x @ w + bias if panels is None else dense(x, w, bias, panels)

        activation = _gelu if panels is None else gelu

        ids = np.asarray(ids, dtype=np.int64)
        b, n = ids.shape
        if panels is not None and b > 1:
            # One text per call: the products of a text then have the same shapes alone or
            # in any batch, so its vector is the same bit for bit whatever BLAS does with
            # more rows (some kernels sum in another order for another row count).
            return np.concatenate([self._encode(ids[i : i + 1], panels) for i in range(b)])
        # Rows are [B * L, dim] for the dense layers, [B, H, L, d] for attention.
        x = (self.word[ids] + self.position[:n] + self.token_type).reshape(b * n, self.dim)
        x = _layer_norm(x, *self.embed_norm, self.eps)
        h, d = self.heads, self.dim // self.heads
        scale = np.float32(1.0 / math.sqrt(d))
        for qkv, qkv_b, out_w, out_b, norm1, up_w, up_b, down_w, down_b, norm2 in self.layers:
            heads = linear(x, qkv, qkv_b).reshape(b, n, 3, h, d).transpose(2, 0, 3, 1, 4)
            q, k, v = heads[0], heads[1], heads[2]  # [B, H, L, d]
            scores = (q @ k.transpose(0, 1, 3, 2)) * scale  # [B, H, L, L]
            scores = np.exp(scores - scores.max(axis=-1, keepdims=True))
            attention = scores / scores.sum(axis=-1, keepdims=True)
            context = (attention @ v).transpose(0, 2, 1, 3).reshape(b * n, self.dim)
            x = _layer_norm(x + linear(context, out_w, out_b), *norm1, self.eps)
            x = _layer_norm(
                x + linear(activation(linear(x, up_w, up_b)), down_w, down_b), *norm2, self.eps
            )
        x = x.reshape(b, n, self.dim)
        pooled = x.mean(axis=1)
        norms = np.linalg.norm(pooled, axis=1, keepdims=True)
        return (pooled / np.maximum(norms, 1e-12)).astype(np.float32)
