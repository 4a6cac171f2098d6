"""Where episodes run: worker processes on this machine, or Ray actors on a cluster.

Every worker holds one in-memory MCP session (`agents.runner.open_session` on
`build_server(config)`) for its whole life, on an event loop of its own thread, and plays its
jobs one after the other through it; the server keeps the simulator env of the last scene,
so jobs handed out in scene order reuse it. A job's failure is returned, not raised, so one
broken episode does not stop the others.
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import queue
import sys
import tempfile
import threading
import traceback
from collections.abc import Iterator, Sequence
from concurrent.futures import Future
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from agents.runner import DEFAULT_LLM_MODEL, LLM_ENV, open_session, run_episode
from glmap_tools.language.backends import LLMSettings
from glmap_tools.launch_env import set_thread_defaults
from glmap_tools.orphans import exit_with_parent
from glmap_tools.server import ServerConfig

SCORER_USED = "scorer_used"  # the f_S a worker's server scored with, in its records


@dataclass(frozen=True)
class Job:
    """One episode for one agent.

    Attributes:
        agent: an `agents.runner.AGENTS` name.
        episode_id: benchmark episode id, e.g. 'bench/objectnav/s03-017'.
        scene: the episode's scene name (jobs are handed out in scene order).
        seed: the episode's seed (the same for every agent).
        max_steps: the step limit.
        trace_dir: where the runner writes the trace and report, or None.
    """

    agent: str
    episode_id: str
    scene: str
    seed: int
    max_steps: int
    trace_dir: str | None = None


@dataclass(frozen=True)
class Outcome:
    """What a worker returns for a job: the result record, or the error it raised."""

    job: Job
    record: dict[str, Any] | None
    error: str | None = None


def _prepare_process(compute_threads: int) -> None:
    set_thread_defaults()
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, str(compute_threads))


def server_llm_settings() -> Any:
    """The worker server's `LLMSettings`: the offline defaults, or with `GLMAP_SCORER=llm`
    (set by `glmap eval --scorer llm`) the LLM scorer on the model, host and prompts of
    `agents.runner.LLM_ENV`."""

    scorer = os.environ.get(LLM_ENV["scorer"]) or "embedding"
    if scorer == "embedding":
        return LLMSettings()
    prompts = os.environ.get(LLM_ENV["prompts"])
    return LLMSettings(
        scorer=scorer,
        model=os.environ.get(LLM_ENV["model"]) or DEFAULT_LLM_MODEL,
        host=os.environ.get(LLM_ENV["host"]) or None,
        prompts=Path(prompts) if prompts else None,
    )


def llm_environment() -> dict[str, str]:
    """The `agents.runner.LLM_ENV` variables set in this process: what `glmap eval` hands a
    worker that does not inherit its environment (a Ray actor on a running cluster)."""

    return {var: os.environ[var] for var in LLM_ENV.values() if var in os.environ}


class EpisodeWorker:
    """Plays jobs through one long-lived in-memory MCP session.

    Args:
        embedder: the server's text embedder ('minilm' or 'hashing').
        compute_threads: BLAS/torch threads of the server (1 per worker avoids oversubscription).
        scene_dirs: scene folders of one's own by split name (`ServerConfig.scene_dirs`).
    """

    def __init__(
        self,
        embedder: str = "minilm",
        compute_threads: int = 1,
        scene_dirs: dict[str, Path] | None = None,
    ) -> None:
        self._scene_dirs = dict(scene_dirs or {})
        _prepare_process(compute_threads)
        self._tmp = tempfile.TemporaryDirectory(prefix="glmap-eval-")
        self._loop = asyncio.new_event_loop()
        self._ready: Future[Any] = Future()
        self._stop: asyncio.Event | None = None
        self._session: Any = None
        self.scorer = "embedding"
        self._thread = threading.Thread(
            target=self._serve, args=(embedder, compute_threads), daemon=True
        )
        self._thread.start()
        self._ready.result()  # raises what opening the session raised

    def _serve(self, embedder: str, compute_threads: int) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._hold(embedder, compute_threads))
        except BaseException as exc:  # surface a failed start in the constructor
            if not self._ready.done():
                self._ready.set_exception(exc)
        finally:
            self._loop.close()

    async def _hold(self, embedder: str, compute_threads: int) -> None:

        llm = server_llm_settings()
        self.scorer = llm.scorer
        config = ServerConfig(
            maps_dir=Path(self._tmp.name) / "maps",
            embedder=embedder,  # type: ignore[arg-type]
            warm_up=False,
            compute_threads=compute_threads,
            llm=llm,
            scene_dirs=self._scene_dirs,
            sim_perception=os.environ.get(LLM_ENV["perception"]) or "auto",  # type: ignore[arg-type]
        )
        self._stop = asyncio.Event()
        async with open_session(config) as session:
            self._session = session
            self._ready.set_result(True)
            await self._stop.wait()

    async def _play(self, job: Job) -> dict[str, Any]:

        result = await run_episode(
            self._session,
            job.episode_id,
            job.agent,
            seed=job.seed,
            out_dir=Path(job.trace_dir) if job.trace_dir else None,
            max_steps=job.max_steps,
        )
        # SCORER_USED: checked against the run's setting by the driver, not stored.
        return {**result.model_dump(), "scene": job.scene, SCORER_USED: self.scorer}

    def run(self, job: Job) -> Outcome:
        """Play one job; an exception becomes the Outcome's error text."""
        try:
            record = asyncio.run_coroutine_threadsafe(self._play(job), self._loop).result()
        except Exception:
            return Outcome(job, None, traceback.format_exc(limit=8))
        return Outcome(job, record)

    def close(self) -> None:
        if self._stop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(timeout=30)
        self._tmp.cleanup()


def _log_to(path: Path) -> None:
    """Send this process's stderr (server logs, tracebacks, EGL warnings) to `path`."""

    path.parent.mkdir(parents=True, exist_ok=True)
    log = path.open("a", encoding="utf-8", buffering=1)
    os.dup2(log.fileno(), 2)
    sys.stderr = log


def _claim(claimed: Any, i: int) -> bool:
    """Mark job `i` taken; False when another worker took it first."""
    with claimed.get_lock():
        if claimed[i]:
            return False
        claimed[i] = 1
        return True


def _process_main(
    embedder: str,
    jobs: list[dict],
    start: int,
    claimed: Any,
    outcomes: Any,
    log: str | None,
    scene_dirs: dict[str, Path] | None = None,
) -> None:
    """A local worker process: walk the job list from `start` (wrapping around), play each
    job no other worker has claimed, and put an Outcome (as a dict) for each. Exits at once
    when the parent process is gone (killed), instead of playing on."""

    exit_with_parent()
    if log:
        _log_to(Path(log))
    try:
        worker = EpisodeWorker(embedder, scene_dirs=scene_dirs)
    except Exception:
        outcomes.put({"fatal": traceback.format_exc(limit=8)})
        return
    try:
        for k in range(len(jobs)):
            i = (start + k) % len(jobs)
            if _claim(claimed, i):
                outcome = worker.run(Job(**jobs[i]))
                outcomes.put({"job": jobs[i], "record": outcome.record, "error": outcome.error})
    finally:
        worker.close()


def run_local(
    jobs: Sequence[Job],
    workers: int,
    embedder: str,
    log_dir: Path | None = None,
    scene_dirs: dict[str, Path] | None = None,
) -> Iterator[Outcome]:
    """Play `jobs` on `workers` local processes; yield each Outcome as it finishes.

    Jobs come in scene order; worker k starts at the k-th of `workers` equal blocks and
    walks on, claiming jobs, so each worker stays on few scenes (its server keeps one scene's
    env) and a worker that finishes its block helps with the others'. Each worker's stderr
    (the server's log) goes to `log_dir`/worker-K.log when given. `scene_dirs` (split name
    -> folder) reaches each worker's server, so it resolves those splits' episode ids.

    Raises:
        RuntimeError: a worker could not start or died (its error is in the message).
    """

    ctx = mp.get_context("spawn")  # no inherited GL context, event loop or thread pools
    out_q: Any = ctx.Queue()
    items = [asdict(job) for job in jobs]
    claimed = ctx.Array("b", len(items))
    n = max(1, min(workers, len(jobs)))
    logs = [str(log_dir / f"worker-{k}.log") if log_dir else None for k in range(n)]
    procs = [
        ctx.Process(
            target=_process_main,
            args=(embedder, items, k * len(items) // n, claimed, out_q, logs[k], scene_dirs),
        )
        for k in range(n)
    ]
    for p in procs:
        p.start()
    left = len(jobs)
    try:
        while left:
            try:
                item = out_q.get(timeout=5.0)
            except queue.Empty:
                if not any(p.is_alive() for p in procs):
                    raise RuntimeError(
                        f"every eval worker exited with {left} episodes left "
                        f"(exit codes {[p.exitcode for p in procs]})"
                    ) from None
                continue
            if "fatal" in item:
                raise RuntimeError(f"an eval worker could not start:\n{item['fatal']}")
            left -= 1
            yield Outcome(Job(**item["job"]), item["record"], item["error"])
    finally:  # after the last outcome workers exit by themselves; otherwise stop them now
        for p in procs:
            p.join(timeout=30 if not left else 0)
            if p.is_alive():
                p.terminate()
                p.join(timeout=5)


def run_inline(
    jobs: Sequence[Job], embedder: str, scene_dirs: dict[str, Path] | None = None
) -> Iterator[Outcome]:
    """Play `jobs` in this process (workers=0), one at a time."""
    worker = EpisodeWorker(embedder, scene_dirs=scene_dirs)
    try:
        for job in jobs:
            yield worker.run(job)
    finally:
        worker.close()
