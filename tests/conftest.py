import os
import sys
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


@pytest.fixture
def running_ray() -> object:
    """A Ray instance on this machine (2 CPUs), shared by consecutive tests that run on Ray
    (a start costs ~6 s of CPU: GCS, raylet and five Python helpers) and stopped after the
    last of them (`pytest_runtest_teardown`: idle, it takes ~4 % of a core). It starts
    without the LLM settings (`agents.runner.LLM_ENV`) in the environment, so its workers
    cannot inherit them, as on a cluster that was already running. `--ray-address local`
    uses an instance running in the process as it is.
    """
    ray = pytest.importorskip("ray")
    from agents.runner import LLM_ENV

    if not ray.is_initialized():
        kept = {var: os.environ.pop(var) for var in LLM_ENV.values() if var in os.environ}
        try:
            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        finally:
            os.environ.update(kept)
    return ray


def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> None:
    """Stop `running_ray`'s instance once the next test does not use it."""
    uses = "running_ray" in getattr(item, "fixturenames", ())
    if uses and (nextitem is None or "running_ray" not in getattr(nextitem, "fixturenames", ())):
        ray = sys.modules.get("ray")  # absent: Ray is not installed and the test was skipped
        if ray is not None and ray.is_initialized():
            ray.shutdown()
