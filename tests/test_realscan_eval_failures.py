"""A crash in an eval episode is reported in the results table and on the terminal with
its cause (one line, and where its traceback is); a rerun that retries failing episodes says
so instead of "played 0 episodes" (issue 40)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from glmap_tools.eval import EvalSpec
from glmap_tools.eval import run as eval_run
from glmap_tools.eval.run import failure_cause, run_eval, run_report
from glmap_tools.eval.workers import Job, Outcome

# What a worker hands back when the server's nav_step crashed: the client's traceback,
# whose last line is the tool error the server worded (issue 41).
CRASH = """Traceback (most recent call last):
  File "/work/main/glmap_tools/eval/workers.py", line 171, in run
    record = asyncio.run_coroutine_threadsafe(self._play(job), self._loop).result()
  File "/work/main/agents/trace.py", line 58, in check
    raise ToolCallError(f"{self.tool} failed: {' '.join(self.texts)}")
agents.trace.ToolCallError: nav_step failed: nav_step failed with an unexpected ValueError:
the array phi contains no zero contour. This is a bug in glmap-tools: please report it.
"""


def spec() -> EvalSpec:
    return EvalSpec(
        task="objectnav",
        split="tune",
        scenes=1,
        episodes_per_scene=2,
        agents=("frontier",),
        max_steps=2,
        embedder="hashing",
    )


@pytest.fixture
def crashing(monkeypatch: pytest.MonkeyPatch) -> None:
    def engine(jobs: list[Job], *args: object, **kw: object) -> Iterator[Outcome]:
        for job in jobs:
            yield Outcome(job, None, CRASH)

    monkeypatch.setattr(eval_run, "_engine", engine)


def test_the_cause_of_a_crash_is_one_readable_line() -> None:
    cause = failure_cause(CRASH)
    assert cause.startswith("nav_step failed: nav_step failed with an unexpected ValueError")
    assert "no zero contour" in cause and "\n" not in cause
    assert "ToolCallError" not in cause and "File " not in cause
    assert failure_cause("") == "no error text came back from the worker"


def test_a_crashed_episode_is_in_the_table_and_on_the_terminal_with_its_cause(
    tmp_path: Path, crashing: None
) -> None:
    out = tmp_path / "run"
    first = run_eval(spec(), out, workers=1, progress=False, resamples=50)
    assert first.ran == 0 and first.tried == 2 and len(first.failures) == 2
    text = (out / "summary.md").read_text(encoding="utf-8")
    assert "## Failed episodes (2 of 2 played in this run)" in text
    assert "| frontier | tune/objectnav/s00-000 | nav_step failed" in text
    assert "no zero contour" in text
    data = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert data["ran"] == 0 and data["tried"] == 2
    failed = data["failed"][0]
    assert "no zero contour" in failed["cause"]
    assert Path(failed["traceback"]).read_text(encoding="utf-8") == CRASH
    report = run_report(first)
    assert "played 0 episodes" not in report
    assert report.splitlines()[0].startswith("played 2 episodes in")
    assert "0 finished" in report and "2 failed" in report
    line = next(ln for ln in report.splitlines() if ln.startswith("FAILED frontier"))
    assert "no zero contour" in line and f"(traceback: {out / 'failures'}" in line
    # A rerun retries them, fails again, and says so.
    again = run_eval(spec(), out, workers=1, progress=False, resamples=50)
    assert again.tried == 2 and again.skipped == 0
    assert "played 0 episodes" not in run_report(again)
