"""The environment defaults every launcher sets first: passive OpenMP waiting.

numba's parallel kernels (the splatting renderer, the Gaussian estimator) run on GNU
OpenMP, whose idle worker threads spin after each parallel region. On cores shared with
other work (the user's LLM, an evaluation), the spinning workers take the core the main
thread needs for the serial code between regions, and a kernel takes about twice as long
(docs/speed.md, "Threads on a busy machine"). `OMP_WAIT_POLICY=PASSIVE` puts them to sleep.

libgomp reads the variable once, when it is loaded: at numba's first parallel kernel, or
earlier when torch is imported (numba's kernels then run on torch's copy). So
`set_thread_defaults()` is the first call of each entry point's `main` (`glmap-mcp`,
`glmap`, `python -m glmap_tools.bench`) and of an eval worker; spawned workers inherit it.
This module imports nothing heavy: `glmap-mcp` answers its handshake before numba loads.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

WAIT_POLICY_ENV = "OMP_WAIT_POLICY"
DEFAULT_WAIT_POLICY = "PASSIVE"


def set_thread_defaults(environ: MutableMapping[str, str] = os.environ) -> None:
    """Default OMP_WAIT_POLICY to PASSIVE; a value the user set (even empty) is kept.

    Takes effect only if no OpenMP runtime is loaded yet: call it before numba runs a
    parallel kernel and before torch is imported.

    Args:
        environ: the environment to set it in (the process's own by default).
    """
    environ.setdefault(WAIT_POLICY_ENV, DEFAULT_WAIT_POLICY)
