"""Where the scans of a many-folder build run: fresh local processes, or Ray tasks.

Every scan runs in a process of its own that ends with it (a local process per scan, a Ray
worker with `max_calls=1`): its peak memory is its own, its memory is returned when it
ends, and a crash (killed for memory, a segfault) fails that scan alone. A scan's failure
comes back as a row, not an exception. Frame progress travels back through a shared
counter (local) or a small counter actor (Ray). Local workers exit when the driver does
(`glmap_tools.orphans.exit_with_parent`).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import socket
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

from glmap_tools.ingest.build import BuildSettings, cpu_seconds
from glmap_tools.ingest.summary import ScanResult
from glmap_tools.orphans import exit_with_parent
from glmap_tools.ray_cluster import connect

# Imports inside functions stay there: numba load on first use: `glmap` imports every command module
# to build its parser; optional: ray.

POLL_S = 0.5  # how often the driver refreshes the frame bar while it waits
# (frames done, frames known) summed over the scans started so far.
FrameCounts = Callable[[int, int], None]


@dataclass(frozen=True)
class ScanTask:
    """One scan to build.

    Attributes:
        scan: the scan's name.
        folder: its folder (the same path on every node of a cluster).
        map: the map file to write.
        settings: how to build.
        overwrite: replace an existing map.
        numba_threads: threads of the estimator's parallel kernels in this scan's process.
    """

    scan: str
    folder: str
    map: str
    settings: BuildSettings
    overwrite: bool = False
    numba_threads: int = 1


def failed(task: ScanTask, error: str) -> ScanResult:
    return ScanResult(
        task.scan, task.folder, task.map, "failed", host=socket.gethostname(), error=error
    )


def build_scan(task: ScanTask, progress: Callable[[int, int], None]) -> ScanResult:
    """Build one scan's map in this process; any failure becomes a "failed" row."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    try:
        import numba

        numba.set_num_threads(max(1, min(task.numba_threads, numba.get_num_threads())))
        from glmap_tools.ingest.build import build_map

        out = Path(task.map)
        if not out.parent.is_dir():
            raise FileNotFoundError(
                f"the out folder {str(out.parent)!r} does not exist on {socket.gethostname()}; "
                "on a cluster, --out must be on storage every node shares."
            )
        built = build_map(
            Path(task.folder), out, task.settings, overwrite=task.overwrite, progress=progress
        )
    except Exception as exc:
        from glmap_tools.errors import GLMapError

        text = str(exc) if isinstance(exc, GLMapError) else traceback.format_exc(limit=6)
        return failed(task, text.strip())
    s = built.stats
    return ScanResult(
        task.scan,
        task.folder,
        task.map,
        "built",
        frames=s.frames,
        instances=s.instances,
        regions=s.regions,
        gaussians=s.gaussians,
        seconds=round(s.seconds, 2),
        frames_per_s=round(s.frames_per_s, 2),
        cpu_s=round(cpu_seconds(), 2),
        peak_rss_mb=round(s.peak_rss_mb, 1),
        host=socket.gethostname(),
    )


# ----------------------------------------------------------------------------- local
def _local_main(task: ScanTask, counts: Any, conn: Any) -> None:
    """A scan's own process: build, add frames to the shared counts, send the row back."""

    exit_with_parent()

    def progress(done: int, total: int) -> None:
        with counts.get_lock():
            counts[0] += done
            counts[1] += total

    conn.send(build_scan(task, progress))
    conn.close()


def run_local(tasks: Sequence[ScanTask], workers: int, frames: FrameCounts) -> Iterator[ScanResult]:
    """Build `tasks` with at most `workers` processes at once; yield each row as it ends."""

    ctx = mp.get_context("spawn")  # a clean process: no inherited threads or BLAS state
    counts: Any = ctx.Array("q", 2)
    todo = list(reversed(tasks))
    running: dict[Any, tuple[Any, ScanTask]] = {}  # pipe end -> (process, task)
    try:
        while todo or running:
            while todo and len(running) < max(1, workers):
                task = todo.pop()
                receive, send = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_local_main, args=(task, counts, send), daemon=True)
                proc.start()
                send.close()  # the child holds the other end: EOF when it is gone
                running[receive] = (proc, task)
            wait([*running, *(p.sentinel for p, _ in running.values())], timeout=POLL_S)
            frames(counts[0], counts[1])
            for receive, (proc, task) in list(running.items()):
                if not (receive.poll() or not proc.is_alive()):
                    continue
                try:
                    row = receive.recv()
                except EOFError:  # ended without a row: killed (memory?) or crashed
                    proc.join()
                    row = failed(
                        task,
                        f"the build process ended without a result (exit code {proc.exitcode}; "
                        "-9 is usually the kernel's out-of-memory killer).",
                    )
                proc.join()
                receive.close()
                del running[receive]
                yield row
        frames(counts[0], counts[1])
    finally:
        for proc, _ in running.values():  # interrupted: stop the scans still building
            proc.terminate()
            proc.join(timeout=5)


# ----------------------------------------------------------------------------- Ray
class _FrameCounter:
    """A Ray actor holding (frames done, frames known) of every task."""

    def __init__(self) -> None:
        self.counts = [0, 0]

    def add(self, done: int, total: int) -> None:
        self.counts[0] += done
        self.counts[1] += total

    def read(self) -> list[int]:
        return self.counts


def _ray_main(task: ScanTask, counter: Any) -> ScanResult:
    """A scan on a Ray worker: frame progress goes to the counter actor every POLL_S."""

    pending = [0, 0]
    last = [time.monotonic()]

    def progress(done: int, total: int) -> None:
        pending[0] += done
        pending[1] += total
        if total or time.monotonic() - last[0] >= POLL_S:
            counter.add.remote(*pending)
            pending[:] = [0, 0]
            last[0] = time.monotonic()

    row = build_scan(task, progress)
    if pending != [0, 0]:
        counter.add.remote(*pending)
    return row


def ray_cpus(address: str, workers: int | None) -> int:
    """Scans at once on Ray: `workers`, else the CPUs of the cluster (of this machine for
    'local')."""
    if workers is not None:
        return workers
    if address == "local":
        return os.cpu_count() or 1
    import ray

    return max(1, int(ray.cluster_resources().get("CPU", 1)))


def run_ray(
    tasks: Sequence[ScanTask], workers: int | None, address: str, frames: FrameCounts
) -> Iterator[ScanResult]:
    """Build `tasks` as Ray tasks (1 CPU each), at most `workers` at once (default: the
    cluster's CPUs); yield each row as it ends.

    Raises:
        RayUnavailableError: Ray missing, or the address not answering.
    """

    ray, started_here = connect(address, ray_cpus("local", workers))
    try:
        at_once = ray_cpus(address, workers)
        counter = ray.remote(num_cpus=0)(_FrameCounter).remote()
        remote = ray.remote(num_cpus=1, max_calls=1, max_retries=0)(_ray_main)
        todo = list(reversed(tasks))
        running: dict[Any, ScanTask] = {}
        while todo or running:
            while todo and len(running) < at_once:
                task = todo.pop()
                running[remote.remote(task, counter)] = task
            done, _ = ray.wait(list(running), num_returns=1, timeout=POLL_S)
            frames(*ray.get(counter.read.remote()))
            for ref in done:
                task = running.pop(ref)
                try:
                    yield ray.get(ref)
                except Exception as exc:  # the worker died (memory, node lost)
                    yield failed(task, f"the Ray task failed: {type(exc).__name__}: {exc}")
        frames(*ray.get(counter.read.remote()))
    finally:
        for ref in running:
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()
