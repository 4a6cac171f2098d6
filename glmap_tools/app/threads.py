"""Intra-op thread limits for the server's lifetime (BLAS and torch), restored afterwards.

A server answers many small requests, often overlapping, on a machine that may be busy:
multi-threaded BLAS and torch then spin-wait against each other and one 10k x 384 product
or one sentence embedding takes ten times longer than on a single thread. Numba kernels
(estimator, renderer) keep their own thread pool and are not affected.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

# Imports inside functions stay there: threadpoolctl load on first use: build_server stays light
# (test_server_startup): the server loads them in the background or on first use; the tools load
# before these do, in the server and the in-process toolset alike; an import that may fail is caught
# where it is used.


@contextmanager
def limited_threads(threads: int | None) -> Iterator[None]:
    """Limit BLAS (via threadpoolctl, when installed) and torch to `threads`; None = as is."""
    if threads is None:
        yield
        return
    undo: list[Callable[[], object]] = []
    try:
        from threadpoolctl import threadpool_limits

        limiter = threadpool_limits(limits=threads, user_api="blas")
        undo.append(limiter.restore_original_limits)
    except ImportError:  # optional: without it BLAS keeps its default threads
        pass
    torch = sys.modules.get("torch")
    if torch is not None:
        before = torch.get_num_threads()
        torch.set_num_threads(threads)
        undo.append(lambda: torch.set_num_threads(before))
    try:
        yield
    finally:
        for restore in reversed(undo):
            restore()
