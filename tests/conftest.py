import os
from collections.abc import Iterator

import pytest

from glmap_tools.launch_env import set_thread_defaults

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
# One BLAS thread per test process (and the servers and workers it starts), as the server
# runs its tools (glmap_tools/app/threads.py): `pytest -n 2` already keeps both cores busy,
# and two processes of two spin-waiting BLAS threads each on two cores made a MiniLM
# embedding ~100x slower (the tau_s calibration test: 141 s instead of ~2 s). A value the
# user exported is kept; tests that are about BLAS threads set their own (`blas_threads`).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
# OpenMP threads of the kernels run in the test processes wait passively when idle, as every
# launcher makes them: `pytest -n 2` is a busy machine (glmap_tools/launch_env.py).
set_thread_defaults()


@pytest.fixture
def blas_threads() -> Iterator[int]:
    """BLAS at the machine's default thread count for one test (a test about what the
    thread count must not change); yields that count."""
    from threadpoolctl import threadpool_info, threadpool_limits

    threads = os.cpu_count() or 1
    with threadpool_limits(limits=threads, user_api="blas"):
        blas = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
        assert blas and set(blas) == {threads}, f"BLAS runs {blas} threads, not {threads}"
        yield threads
