"""Every launcher defaults OMP_WAIT_POLICY to PASSIVE before a kernel runs, and keeps a
value the user exported (glmap_tools.launch_env)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

# Each entry point's main, run in a fresh process with --help (which exits after the
# settings are made), then the environment the kernels would run under.
ENTRY_POINTS = {
    "glmap-mcp": "from glmap_tools.server.cli import main; main(['--help'])",
    "glmap": "from glmap_tools.cli import main; main(['--help'])",
    "bench": "from glmap_tools.bench.__main__ import main; main(['--help'])",
    "eval worker": "from glmap_tools.eval.workers import _prepare_process; _prepare_process(1)",
}
VARIABLES = ("OMP_WAIT_POLICY", "NUMBA_THREADING_LAYER")
SHOW = f"import os; print(*(os.environ.get(v) for v in {VARIABLES!r}))"


def launch(entry: str, **env: str) -> list[str]:
    """The OMP_WAIT_POLICY and NUMBA_THREADING_LAYER a process sees after `entry` starts."""
    environ = {k: v for k, v in os.environ.items() if k not in VARIABLES}
    code = f"try:\n    {ENTRY_POINTS[entry]}\nexcept SystemExit:\n    pass\n{SHOW}"
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={**environ, **env},
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout
    return out.splitlines()[-1].split()


@pytest.mark.parametrize("entry", list(ENTRY_POINTS))
def test_a_launcher_makes_idle_openmp_threads_wait_passively(entry):
    assert launch(entry) == ["PASSIVE", "None"]


@pytest.mark.parametrize("entry", list(ENTRY_POINTS))
def test_a_wait_policy_or_threading_layer_the_user_exported_is_kept(entry):
    kept = launch(entry, OMP_WAIT_POLICY="ACTIVE", NUMBA_THREADING_LAYER="workqueue")
    assert kept == ["ACTIVE", "workqueue"]
