"""The framework venvs that .ci/frameworks.sh builds, and running a script in one of them."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
VENVS = REPO / ".ci" / "venvs"
GLMAP_MCP = Path(sys.executable).parent / "glmap-mcp"
# GLMAP_FRAMEWORK_VENVS=0 skips the tests that need them (e.g. a machine without PyPI).
DISABLED = os.environ.get("GLMAP_FRAMEWORK_VENVS") == "0"


def python_of(name: str) -> Path:
    """The python of framework venv `name`; a missing venv fails with the command that builds it."""
    python = VENVS / name / "bin" / "python"
    if DISABLED:
        pytest.skip("GLMAP_FRAMEWORK_VENVS=0: framework venvs disabled")
    if not python.exists():
        pytest.fail(
            f"no {name} venv at {python.parent.parent}: build it with `bash .ci/frameworks.sh` "
            "(or set GLMAP_FRAMEWORK_VENVS=0 to skip the framework tests)"
        )
    return python


def run_json(name: str, script: str, *args: str, timeout: float = 600) -> dict[str, Any]:
    """Run tests/frameworks/SCRIPT in venv `name`; its stdout's last line is a JSON object."""
    done = subprocess.run(
        [str(python_of(name)), str(REPO / "tests" / "frameworks" / script), *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert done.returncode == 0, f"{script} {' '.join(args)} failed:\n{done.stderr[-4000:]}"
    lines = done.stdout.strip().splitlines()
    assert lines, f"{script} printed nothing; stderr:\n{done.stderr[-2000:]}"
    return json.loads(lines[-1])
