"""Episodes on a Ray cluster: one `EpisodeWorker` per Ray actor (1 CPU each).

`--ray-address` is checked and connected to by `glmap_tools.ray_cluster` (which many-folder
builds share; this module still exports its `check_address`, `CONNECT_TIMEOUT_S` and
`RayUnavailableError`): 'local' starts a Ray instance on this machine with `workers` CPUs,
'auto', 'HOST:PORT' or 'ray://HOST:PORT' reach a cluster, and an address that does not
answer fails within `CONNECT_TIMEOUT_S`. Every node needs glmap-tools (with its `ray` extra)
installed. The LLM settings of `glmap eval` (`--scorer llm`, `--model`,
`--ollama-host`, `--prompts`: `agents.runner.LLM_ENV`) are handed to each actor, since actors
on a cluster that was already running do not inherit the driver's environment; a `--prompts`
folder, like a `--scenes-dir` folder, must exist at the same path on every node.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from glmap_tools.eval.workers import EpisodeWorker, Job, Outcome, llm_environment
from glmap_tools.ray_cluster import CONNECT_TIMEOUT_S as CONNECT_TIMEOUT_S
from glmap_tools.ray_cluster import RayUnavailableError as RayUnavailableError
from glmap_tools.ray_cluster import check_address as check_address
from glmap_tools.ray_cluster import connect


class _RayWorker:
    """The body of a Ray actor: an EpisodeWorker that lives as long as the actor."""

    def __init__(
        self, embedder: str, llm_env: dict[str, str], scene_dirs: dict[str, Path] | None = None
    ) -> None:
        os.environ.update(llm_env)  # the actor's own process: the driver's LLM settings
        self.worker = EpisodeWorker(embedder, scene_dirs=scene_dirs)

    def run(self, job: Job) -> Outcome:
        return self.worker.run(job)


def run_ray(
    jobs: Sequence[Job],
    workers: int,
    embedder: str,
    address: str,
    scene_dirs: dict[str, Path] | None = None,
) -> Iterator[Outcome]:
    """Play `jobs` on `workers` Ray actors; yield each Outcome as it finishes.

    `scene_dirs` (split name -> folder) reaches every actor's server; the folders must be
    at the same paths on every node.

    Raises:
        RayUnavailableError: Ray missing or the address not answering (within 10 s).
    """
    ray, started_here = connect(address, workers)
    actors: list[Any] = []
    try:
        actor_cls = ray.remote(num_cpus=1)(_RayWorker)
        n = max(1, min(workers, len(jobs)))
        llm_env = llm_environment()
        actors = [actor_cls.remote(embedder, llm_env, scene_dirs) for _ in range(n)]
        # As on local workers: actor k starts at the k-th block of the scene-ordered jobs.
        cursors = [k * len(jobs) // n for k in range(n)]
        taken = [False] * len(jobs)
        running: dict[Any, int] = {}  # object ref -> actor index

        def submit(k: int) -> None:
            for step in range(len(jobs)):
                i = (cursors[k] + step) % len(jobs)
                if not taken[i]:
                    taken[i] = True
                    cursors[k] = i + 1
                    running[actors[k].run.remote(jobs[i])] = k
                    return

        for k in range(n):
            submit(k)
        while running:
            done, _ = ray.wait(list(running), num_returns=1)
            k = running.pop(done[0])
            yield ray.get(done[0])
            submit(k)
    finally:
        for actor in actors:
            ray.kill(actor)
        if started_here:
            ray.shutdown()
