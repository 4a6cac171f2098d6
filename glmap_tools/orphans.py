"""Worker processes that exit with their parent (issue 27 item 5).

`glmap eval` plays episodes in spawned worker processes (eval.workers.run_local) and answers
SQA scenes in a process pool (eval.sqa); `glmap build` over many folders builds each scan in
a process of its own (ingest.engines). Killing the parent (SIGTERM, SIGKILL, a closed
terminal) ran no cleanup, and a worker kept playing for 11 minutes. `exit_with_parent()`,
called first thing in a worker (or as a pool's `initializer`), starts a daemon thread that
waits on the parent's sentinel and ends the worker at once when the parent is gone, whatever
killed it.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from multiprocessing.connection import wait

ORPHAN_EXIT_CODE = 70  # what a worker exits with when its parent went away first


def exit_with_parent() -> bool:
    """In a multiprocessing child: exit (os._exit) as soon as the parent process is gone.

    Returns:
        Whether a watchdog was started (False outside a multiprocessing child).
    """
    parent = multiprocessing.parent_process()
    if parent is None or parent.sentinel is None:
        return False
    sentinel = parent.sentinel

    def watch() -> None:
        wait([sentinel])  # readable (EOF) once the parent's end of the pipe closes: it died
        os._exit(ORPHAN_EXIT_CODE)

    threading.Thread(target=watch, name="glmap-exit-with-parent", daemon=True).start()
    return True
