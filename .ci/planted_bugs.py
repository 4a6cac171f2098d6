"""Plant each bug below in a copy of the tree and check that a test fails on it.

Each bug breaks one rule of the paper or of a contract the tools promise (Eq. 7's kernel,
frontier connectivity, the planner's turn rule and arrived radius, the store's next_id, the
calibrated match threshold, the stdio relay's one answer per request). The tests pass on
the real code (CI runs them); here each bug must make at least one of them fail.

    python .ci/planted_bugs.py              # every bug; a line per bug, exit 1 if one survives
    python .ci/planted_bugs.py eq7-sigma    # one bug by name
    python .ci/planted_bugs.py --commit=abc123 ...   # the tree of a commit (default HEAD)

The bug's code is found by its text anywhere under glmap_tools/, so files may move; a text
found in no file or in several is reported as such (update the bug's text, not the test).
Takes ~10 minutes on 2 cores.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Bug:
    name: str
    what: str
    old: str
    new: str
    tests: tuple[str, ...]


NAV = ("tests/test_nav_value.py", "tests/test_nav_frontiers.py", "tests/test_nav_planner.py")
MOTION = ("tests/test_nav_motion.py", "tests/test_nav_planner.py", "tests/test_nav_decide.py")
BUGS = (
    Bug(
        "eq7-sigma",
        "Eq. 7 kernel exp(-x^2/sigma^2) instead of exp(-x^2/2 sigma^2)",
        "g = np.exp(-0.5 * (x / sigma_cells) ** 2)",
        "g = np.exp(-1.0 * (x / sigma_cells) ** 2)",
        NAV,
    ),
    Bug(
        "frontier-reach-8",
        "frontier reachability 8-connected (through a diagonal pinch)",
        "labels, _ = ndimage.label(trav)",
        "labels, _ = ndimage.label(trav, structure=EIGHT)",
        NAV,
    ),
    Bug(
        "frontier-min-size",
        "frontier clusters of exactly min_size cells dropped",
        "if b - a < min_size:",
        "if b - a <= min_size:",
        NAV,
    ),
    Bug(
        "turn-direction",
        "the controller turns the wrong way",
        'return Drive("turn_left" if turns > 0 else "turn_right", turns, True, gain)',
        'return Drive("turn_left" if turns < 0 else "turn_right", turns, True, gain)',
        MOTION,
    ),
    Bug(
        "forward-before-turn",
        "moves forward while the best heading is one turn away",
        "if turns == 0:\n        return Drive(",
        "if abs(turns) <= 1:\n        return Drive(",
        MOTION,
    ),
    Bug(
        "arrived-radius",
        "the plan stops a whole step from its goal instead of half",
        "if math.dist(agent_xy, end_xy) <= config.forward_step / 2:",
        "if math.dist(agent_xy, end_xy) <= config.forward_step:",
        MOTION,
    ),
    Bug(
        "situate-region-margin",
        "a region needs no margin over the anchor object to place the agent",
        "REGION_MARGIN = 0.1",
        "REGION_MARGIN = 0.0",
        ("tests/test_sqa_situate.py",),
    ),
    Bug(
        "store-next-id",
        "a store whose next_id equals its largest unit id is accepted",
        "if next_id <= top:",
        "if next_id < top:",
        ("tests/test_map_store.py", "tests/test_store_fuzz.py"),
    ),
    Bug(
        "minilm-tau-match",
        "MiniLM's match threshold is not the calibrated one",
        "default_tau_match: float = 0.49",
        "default_tau_match: float = 0.45",
        ("tests/test_search_quality.py",),
    ),
    Bug(
        "relay-answers-twice",
        "the stdio relay sends the SDK's answer to a request it answered early",
        "                if sent is not None:\n                    return\n",
        "",
        ("tests/test_server_handshake.py",),
    ),
    Bug(
        "relay-paginated-list",
        "the stdio relay answers a paginated tools/list (one with a cursor) early",
        'elif method == TOOLS_LIST and not params.get("cursor"):',
        "elif method == TOOLS_LIST:",
        ("tests/test_server_handshake.py",),
    ),
)


def copy_tree(dest: Path, commit: str) -> None:
    """The files of `commit`, written to `dest` (uncommitted edits are not planted in)."""
    archive = subprocess.run(
        ["git", "archive", "--format=tar", commit], cwd=ROOT, check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-xf", "-"], cwd=dest, input=archive, check=True)


def plant(tree: Path, bug: Bug) -> tuple[Path, str] | str:
    """(the file, its text before) with `bug` planted, or why it could not be."""
    hits = [p for p in (tree / "glmap_tools").rglob("*.py") if bug.old in p.read_text()]
    if len(hits) != 1:
        return f"its text is in {len(hits)} files, not 1"
    path = hits[0]
    text = path.read_text()
    if text.count(bug.old) != 1:
        return f"its text is {text.count(bug.old)} times in {path.relative_to(tree)}"
    path.write_text(text.replace(bug.old, bug.new))
    return path, text


def run_tests(tree: Path, bug: Bug) -> tuple[int, str]:
    """(pytest's exit code, the first failing test) on the planted tree."""
    env = {
        "PYTHONPATH": str(tree),
        "PYOPENGL_PLATFORM": "egl",
        "HF_HUB_OFFLINE": "1",
        "PATH": "/usr/bin:/bin",
        "HOME": str(Path.home()),
    }
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *bug.tests]
    done = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    failed = [ln.split(" ")[1] for ln in done.stdout.splitlines() if ln.startswith("FAILED ")]
    return done.returncode, failed[0] if failed else ""


def main(names: list[str]) -> int:
    commit = "HEAD"
    if names and names[0].startswith("--commit="):
        commit, names = names[0].split("=", 1)[1], names[1:]
    bugs = [b for b in BUGS if not names or b.name in names]
    unknown = set(names) - {b.name for b in BUGS}
    if unknown:
        print(f"no bug named {sorted(unknown)}; the bugs: {', '.join(b.name for b in BUGS)}")
        return 2
    survived = 0
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp)
        copy_tree(tree, commit)
        for bug in bugs:
            start = time.monotonic()
            planted = plant(tree, bug)
            if isinstance(planted, str):
                print(f"{bug.name:24s} NOT PLANTED: {planted}")
                survived += 1
                continue
            path, before = planted
            try:
                code, killer = run_tests(tree, bug)
            finally:
                path.write_text(before)
            took = time.monotonic() - start
            if code == 1 and killer:
                print(f"{bug.name:24s} killed by {killer}  ({took:.0f} s)")
            else:
                survived += 1
                print(f"{bug.name:24s} SURVIVED (pytest exit {code}): {bug.what}  ({took:.0f} s)")
    print(f"{len(bugs) - survived} of {len(bugs)} planted bugs fail a test")
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
