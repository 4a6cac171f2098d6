"""Killing `glmap eval` ends its worker processes too (issue 27 item 5)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
ROOT = Path(__file__).resolve().parents[1]


def children(pid: int) -> dict[int, str]:
    """{pid: command line} of the live (not zombie) processes whose parent is `pid`."""
    out: dict[int, str] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()  # after "pid (comm) "
        if int(fields[1]) == pid and fields[0] != "Z":
            out[int(entry.name)] = cmdline
    return out


def alive(pid: int) -> bool:
    """Whether `pid` is a live process (a zombie is not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def wait_for(check, timeout_s: float) -> bool:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if check():
            return True
        time.sleep(0.1)
    return check()


def kill_and_count_survivors(
    command: list[str], workers: int, sig: signal.Signals, tmp_path: Path, marker: str = ""
) -> tuple[list[int], str]:
    """Start `command`, wait for `workers` child processes (with `marker` in their command
    line), send `sig` to the parent only; return (the children still alive 10 s later, the
    parent's stderr)."""
    env = {**os.environ, "PYOPENGL_PLATFORM": "egl", "HF_HUB_OFFLINE": "1"}
    log = (tmp_path / "stderr.txt").open("w")
    proc = subprocess.Popen(command, cwd=ROOT, env=env, stdout=log, stderr=log)
    seen: dict[int, str] = {}
    try:

        def started() -> bool:
            seen.update(children(proc.pid))
            return sum(marker in c for c in seen.values()) >= workers

        assert wait_for(started, 120), (seen, (tmp_path / "stderr.txt").read_text()[-2000:])
        proc.send_signal(sig)
        proc.wait(timeout=30)
        wait_for(lambda: not any(alive(p) for p in seen), 10)
        return [p for p in seen if alive(p)], (tmp_path / "stderr.txt").read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
        for pid in seen:  # the test's own strays, by pid
            if alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_sigterm_to_glmap_eval_ends_its_episode_workers(tmp_path):
    command = [
        sys.executable,
        "-m",
        "glmap_tools.cli",
        "eval",
        "objectnav",
        "--split",
        "tune",
        "--scenes",
        "1",
        "--episodes-per-scene",
        "2",
        "--agents",
        "random",
        "--workers",
        "2",
        "--embedder",
        "hashing",
        "--out",
        str(tmp_path / "out"),
    ]
    survivors, stderr = kill_and_count_survivors(
        command, 2, signal.SIGTERM, tmp_path, marker="multiprocessing"
    )
    assert survivors == [], (
        f"workers {survivors} outlived glmap eval; its stderr:\n{stderr[-2000:]}"
    )


def test_a_killed_parent_ends_its_process_pool(tmp_path):
    # What sqa.py's pool gets through `initializer=exit_with_parent`; SIGKILL runs no cleanup.
    script = (
        "import time\n"
        "from concurrent.futures import ProcessPoolExecutor\n"
        "from glmap_tools.eval.orphans import exit_with_parent\n"
        "if __name__ == '__main__':\n"
        "    with ProcessPoolExecutor(2, initializer=exit_with_parent) as pool:\n"
        "        list(pool.map(time.sleep, [600, 600]))\n"
    )
    survivors, stderr = kill_and_count_survivors(
        [sys.executable, "-c", script], 2, signal.SIGKILL, tmp_path
    )
    assert survivors == [], stderr
