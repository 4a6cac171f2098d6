"""Run an evaluation: select episodes, skip finished ones, play the rest, write the table."""

from __future__ import annotations

import json
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from glmap_tools.errors import InvalidInputError
from glmap_tools.eval.by_difficulty import (
    difficulty_markdown,
    difficulty_rows,
    episode_difficulties,
)
from glmap_tools.eval.ray_engine import check_address, run_ray
from glmap_tools.eval.results import ResultsDir, _safe, write_json
from glmap_tools.eval.spec import (
    EvalSpec,
    episode_key,
    episode_seed,
    parse_agents,
    select_episodes,
)
from glmap_tools.eval.stats import DEFAULT_RESAMPLES, check_resamples
from glmap_tools.eval.table import Summary, markdown, summarize
from glmap_tools.eval.workers import SCORER_USED, Job, Outcome, run_inline, run_local


@dataclass
class EvalRun:
    """What `run_eval` did.

    Attributes:
        spec: the evaluation.
        out: the results folder.
        records: agent -> episode id -> record, for the selected episodes that are finished.
        summary: the table's numbers over `records`.
        ran: episodes played to the end now; skipped: episodes found finished in `out`.
        failures: jobs whose episode raised (their error text is in each Outcome; the
            text is kept in `failure_file`, its cause in one line is `failure_cause`).
        wall_s: seconds spent playing.
        mixed: `out` holds results of more than one setting (see ResultsDir).
        total: (agent, episode) pairs selected.
        complete_only: the table counts only episodes every agent finished.
        by_difficulty: the table split by difficulty bins (`eval.by_difficulty`).
    """

    spec: EvalSpec
    out: Path
    records: dict[str, dict[str, dict[str, Any]]]
    summary: Summary
    ran: int
    skipped: int
    failures: list[Outcome] = field(default_factory=list)
    wall_s: float = 0.0
    mixed: bool = False
    total: int = 0
    complete_only: bool = False
    by_difficulty: list[dict[str, Any]] = field(default_factory=list)

    @property
    def tried(self) -> int:
        """Episodes this run set out to play: finished now plus failed."""
        return self.ran + len(self.failures)

    @property
    def episodes_per_hour(self) -> float:
        """Episodes played per hour of wall time in this run (0 when none ran)."""
        return self.ran / self.wall_s * 3600.0 if self.ran and self.wall_s > 0 else 0.0

    def failure_file(self, failure: Outcome) -> Path:
        """Where the failed episode's full error text (its traceback) is kept."""
        return failure_path(self.out, failure)


FAILURES_DIR = "failures"  # out/failures/<agent>/<episode>.txt: each failed episode's traceback
_EXC_PREFIX = re.compile(r"^(?:[A-Za-z_][\w.]*\.)?[A-Z]\w*(?:Error|Exception|Warning)?: ")
CAUSE_CHARS = 300


def failure_path(out: Path, failure: Outcome) -> Path:
    """out/failures/<agent>/<episode>.txt for a failed episode."""
    return out / FAILURES_DIR / _safe(failure.job.agent) / f"{_safe(failure.job.episode_id)}.txt"


def failure_cause(error: str | None) -> str:
    """One readable line from a failed episode's error text (a traceback): its last line,
    the client's wrapper type (`agents.trace.ToolCallError: `) taken off, white space
    collapsed, cut to `CAUSE_CHARS`."""
    lines = [ln.strip() for ln in (error or "").strip().splitlines() if ln.strip()]
    if not lines:
        return "no error text came back from the worker"
    # The exception line may run over several lines (a message with newlines): from the
    # last line that starts with an exception's name on.
    start = max(
        (k for k, ln in enumerate(lines) if _EXC_PREFIX.match(ln) and not ln.startswith("File ")),
        default=len(lines) - 1,
    )
    text = " ".join(lines[start:])
    first = _EXC_PREFIX.match(text)
    if first and ("ToolCallError" in first.group(0) or "RuntimeError" in first.group(0)):
        text = text[first.end() :]
    text = " ".join(text.split())
    return text if len(text) <= CAUSE_CHARS else text[: CAUSE_CHARS - 1] + "…"


def run_report(run: EvalRun) -> str:
    """What `glmap eval` prints after the table: episodes tried, finished and failed (a
    rerun that retried failing episodes says so, never "played 0"), and each failure's cause
    in one line with where its traceback is."""
    head = (
        f"played {run.tried} episodes in {run.wall_s:.0f} s: {run.ran} finished "
        f"({run.episodes_per_hour:.0f} per hour), {len(run.failures)} failed; "
        f"skipped {run.skipped} finished ones; results in {run.out}"
    )
    if not run.tried:
        head = (
            f"played 0 episodes: the {run.skipped} selected were finished already; "
            f"results in {run.out}"
        )
    lines = [head]
    for f in run.failures[:5]:
        lines.append(
            f"FAILED {f.job.agent} on {f.job.episode_id}: {failure_cause(f.error)} "
            f"(traceback: {run.failure_file(f)})"
        )
    if len(run.failures) > 5:
        lines.append(f"... and {len(run.failures) - 5} more in {run.out / FAILURES_DIR}")
    if run.failures:
        lines.append(
            f"{len(run.failures)} episodes failed (tracebacks: {run.out / FAILURES_DIR}; server "
            f"logs: {run.out / 'logs'}); rerun the same command to retry them."
        )
    return "\n".join(lines)


def _engine(
    jobs: list[Job],
    workers: int,
    embedder: str,
    ray_address: str | None,
    log_dir: Path,
    scene_dirs: dict[str, Path],
) -> Iterator[Outcome]:
    if ray_address:
        return run_ray(jobs, max(1, workers), embedder, ray_address, scene_dirs)
    if workers == 0:
        return run_inline(jobs, embedder, scene_dirs)
    return run_local(jobs, workers, embedder, log_dir, scene_dirs)


def _check_scorer(outcome: Outcome, scorer: str) -> Outcome:
    """The outcome without the worker's `SCORER_USED`; a failure when it is not `scorer`
    (the run's LLM settings did not reach that worker), so no record is mislabelled."""
    if outcome.record is None:
        return outcome
    record = dict(outcome.record)
    used = record.pop(SCORER_USED, scorer)
    if used != scorer:
        error = (
            f"the worker scored with f_S {used!r}, the run asks for {scorer!r}: its LLM "
            "settings (GLMAP_SCORER, GLMAP_LLM_MODEL, OLLAMA_HOST) did not reach it"
        )
        return Outcome(outcome.job, None, error)
    return Outcome(outcome.job, record)


def run_eval(
    spec: EvalSpec,
    out: Path,
    *,
    workers: int = 2,
    ray_address: str | None = None,
    mix_configs: bool = False,
    traces: bool = False,
    resamples: int = DEFAULT_RESAMPLES,
    progress: bool = True,
    play: bool = True,
    complete_only: bool = False,
) -> EvalRun:
    """Play every (episode, agent) of `spec` not yet in `out`, then summarize all of them.

    Args:
        spec: what to evaluate.
        out: the results folder (see `glmap_tools.eval.results`).
        workers: local worker processes (0 = play in this process), or Ray actors.
        ray_address: run on Ray ('local', 'auto', HOST:PORT, ray://HOST:PORT) instead.
        mix_configs: add to a folder whose results were run with other settings.
        traces: also write each episode's tool-call trace and report under out/traces/.
        resamples: bootstrap resamples of the table's intervals.
        progress: show a tqdm progress bar on stderr.
        play: False only rewrites the table from the episodes already finished in `out`.
        complete_only: the table counts only episodes that every agent finished (so every
            row covers the same episodes, e.g. after a run was stopped part way).

    Raises:
        InvalidInputError: unknown agents, too many scenes or episodes, negative workers,
            or a folder of other settings (nothing is written then).
    """
    parse_agents(spec.agents)
    if workers < 0:
        raise InvalidInputError(f"--workers {workers} must be 0 (in process) or more.")
    check_resamples(resamples)
    if ray_address:
        check_address(ray_address)  # fail before anything is written
    selected = select_episodes(
        spec.task, spec.split, spec.scenes, spec.episodes_per_scene, spec.scene_dirs
    )
    results = ResultsDir(out, spec.result_config(), mix_configs=mix_configs)
    records: dict[str, dict[str, dict[str, Any]]] = {a: {} for a in spec.agents}
    keys = {be.episode_id: episode_key(be) for be in selected}
    jobs = _pending_jobs(spec, selected, results, records, keys, traces, mix_configs)
    skipped = len(selected) * len(spec.agents) - len(jobs)
    if not play:
        jobs = []
    failures: list[Outcome] = []
    start = time.perf_counter()
    if jobs:
        failures = _play(
            jobs, spec, workers, ray_address, results, records, keys, skipped, progress
        )
    wall = time.perf_counter() - start
    if complete_only:
        common = set.intersection(*(set(r) for r in records.values()))
        records = {a: {e: r for e, r in rs.items() if e in common} for a, rs in records.items()}
    summary = summarize(records, spec.agents, resamples=resamples)
    difficulties = episode_difficulties(selected)
    binned = difficulty_rows(records, spec.agents, difficulties, resamples=resamples)
    run = EvalRun(
        spec,
        results.root,
        records,
        summary,
        len(jobs) - len(failures),
        skipped,
        failures,
        wall,
        results.mixed,
        len(selected) * len(spec.agents),
        complete_only,
        binned,
    )
    _write_summary(run)
    return run


def _pending_jobs(
    spec: EvalSpec,
    selected: list[Any],
    results: ResultsDir,
    records: dict[str, dict[str, dict[str, Any]]],
    keys: dict[str, str],
    traces: bool,
    mix_configs: bool,
) -> list[Job]:
    """The (episode, agent) jobs not yet finished in `results`; the finished ones go into
    `records`.

    Raises:
        InvalidInputError: finished episodes were played on other benchmark files (a
            regenerated split) and `mix_configs` is off.
    """
    jobs: list[Job] = []
    stale: list[str] = []
    for be in selected:  # scene order, so each worker's server reuses its env
        seed = episode_seed(spec.seed, be.episode_id)
        for agent in spec.agents:
            record = results.load(agent, be.episode_id)
            if record is not None and record.get("episode_key") not in (None, keys[be.episode_id]):
                stale.append(f"{agent} on {be.episode_id}")
            elif record is not None:
                records[agent][be.episode_id] = record
                continue
            trace = results.trace_dir(agent, be.episode_id) if traces else None
            jobs.append(
                Job(agent, be.episode_id, be.scene, seed, spec.max_steps, str(trace or "") or None)
            )
    if stale and not mix_configs:
        raise InvalidInputError(
            f"{len(stale)} finished episodes in {results.root} were played on other benchmark "
            f"files (e.g. {stale[0]}: the split was regenerated since); choose another --out, "
            "or pass --mix-configs to replay them."
        )
    return jobs


def _play(
    jobs: list[Job],
    spec: EvalSpec,
    workers: int,
    ray_address: str | None,
    results: ResultsDir,
    records: dict[str, dict[str, dict[str, Any]]],
    keys: dict[str, str],
    skipped: int,
    progress: bool,
) -> list[Outcome]:
    """Play `jobs` on local workers or Ray, saving each record (into `records` too) and
    each failure's error under the results folder; the failures."""
    failures: list[Outcome] = []
    where = f"Ray ({ray_address})" if ray_address else f"{workers} workers"
    with tqdm(
        total=len(jobs) + skipped,
        initial=skipped,
        desc=f"{spec.task} {spec.split} on {where}",
        unit="ep",
        disable=not progress,
        file=sys.stderr,
    ) as bar:
        for outcome in _engine(
            jobs, workers, spec.embedder, ray_address, results.root / "logs", spec.scene_dirs
        ):
            outcome = _check_scorer(outcome, spec.scorer)
            if outcome.record is None:
                failures.append(outcome)
                failed = failure_path(results.root, outcome)
                failed.parent.mkdir(parents=True, exist_ok=True)
                failed.write_text(outcome.error or "", encoding="utf-8")
                bar.set_postfix(failed=len(failures))
            else:
                job = outcome.job
                stored = results.save({**outcome.record, "episode_key": keys[job.episode_id]})
                records[job.agent][job.episode_id] = stored
            bar.update(1)
    return failures


def _write_summary(run: EvalRun) -> None:
    s = run.spec
    head = (
        f"# {s.task} on "
        + (f"the {s.split} split" if s.scenes_dir is None else f"{s.split} ({s.scenes_dir})")
        + "\n\n"
        f"Selection: the first {s.scenes or 'all'} scenes x {s.episodes_per_scene or 'all'} "
        f"episodes of each; seed {s.seed}, max_steps {s.max_steps}, embedder {s.embedder}, "
        + (f"scorer llm ({s.llm_model}), " if s.scorer == "llm" else "")
        + f"images {s.result_config()['image_size']}. Finished: "
        f"{sum(len(r) for r in run.records.values())} of {run.total} (agent, episode) pairs"
        f"{' (only episodes every agent finished)' if run.complete_only else ''}.\n\n"
    )
    if run.mixed:
        head += "Warning: this folder mixes results run with different settings (eval.json).\n\n"
    by_difficulty = "\n## By difficulty\n\n" + difficulty_markdown(run.by_difficulty, s.agents)
    (run.out / "summary.md").write_text(
        head + markdown(run.summary) + by_difficulty + _failed_markdown(run), encoding="utf-8"
    )
    data = {
        "config": s.result_config(),
        "selection": {"scenes": s.scenes, "episodes_per_scene": s.episodes_per_scene},
        "agents": list(s.agents),
        "ran": run.ran,
        "tried": run.tried,
        "skipped": run.skipped,
        "failed": [
            {
                "agent": f.job.agent,
                "episode_id": f.job.episode_id,
                "cause": failure_cause(f.error),
                "traceback": str(run.failure_file(f)),
                "error": f.error,
            }
            for f in run.failures
        ],
        "wall_s": round(run.wall_s, 2),
        "episodes_per_hour": round(run.episodes_per_hour, 1),
        "mixed_configs": run.mixed,
        **run.summary.to_json(),
        "by_difficulty": run.by_difficulty,
    }
    write_json(run.out / "summary.json", json.loads(json.dumps(data)))


def _failed_markdown(run: EvalRun) -> str:
    """A table of the episodes that failed in this run: agent, episode, cause, traceback."""
    if not run.failures:
        return ""
    lines = [
        "",
        f"## Failed episodes ({len(run.failures)} of {run.tried} played in this run)",
        "",
        "| Agent | Episode | Cause | Traceback |",
        "|---|---|---|---|",
    ]
    for f in run.failures:
        cause = failure_cause(f.error).replace("|", "\\|")
        where = run.failure_file(f).relative_to(run.out)
        lines.append(f"| {f.job.agent} | {f.job.episode_id} | {cause} | {where} |")
    return "\n".join(lines) + "\n"
