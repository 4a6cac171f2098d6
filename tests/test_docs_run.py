"""Every code block of README.md and docs/*.md runs (or parses) as written.

Blocks, in order, per document, in one temporary folder that links to the repository's
top-level files and folders (so commands find `tests/...` or `prompts/` as from the
repository root) and takes everything they write:

- ```json: parses; a block preceded by `<!-- docs-test: file NAME -->` is also written to
  NAME for the commands after it; an MCP client config names its server by absolute path
  (the docs' own advice).
- ```python: runs as a script (subprocess, the repository on the path).
- ```bash / ```sh: each command runs: `glmap ...` in process, `python -m MODULE ...`
  through the module's `main`. Commands that start a server, set up the environment or
  need another program are in `NOT_RUN` with the reason.
- ```text (output, usage synopses): not run.

Slow commands (a minute or more on two busy cores: a demo episode, a MiniLM map build, a
tour, a benchmark; `SLOW`) and blocks preceded by `<!-- docs-test: slow -->` are only checked
by default: python compiles, `glmap` arguments parse, other commands answer --help.
`GLMAP_DOCS_SLOW=1` runs them all. Any other marker, e.g. `<!-- docs-test: live-ollama -->`,
names what the block needs that a test machine lacks, and the block is not run; except
`<!-- docs-test: venv NAME -->`: a python block run by the framework venv .ci/venvs/NAME
(`bash .ci/frameworks.sh` builds them; GLMAP_FRAMEWORK_VENVS=0 skips such blocks) as a new
user runs it: neither this venv's `bin` on PATH nor the repository on the Python path, and
$GLMAP_MCP set to this venv's `glmap-mcp` by absolute path, as the pages' setup says.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

from glmap_tools import cli
from glmap_tools.server.linger import lingering_servers

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
RUN_SLOW = os.environ.get("GLMAP_DOCS_SLOW") == "1"
MARKER = re.compile(r"<!--\s*docs-test:\s*(?P<what>[\w-]+)\s*(?P<arg>\S*)\s*-->")
FENCE = re.compile(r"^```(?P<lang>[\w.+-]*)\s*$")
# Command heads that are not run, and why.
NOT_RUN = {
    "bash .ci/setup": "sets up the environment this test runs in",
    "bash .ci/run": "is the whole CI job, this test included",
    "bash .ci/frameworks.sh": "builds the framework venvs (CI runs it before the tests)",
    "glmap-mcp": "starts a server that runs until stopped (tests/test_server_transports.py)",
    "python -m glmap_tools.server": "starts a server (tests/test_server_transports.py)",
    "python -m pytest": "is the test suite itself",
    "claude": "needs the Claude Code CLI",
    "which": "depends on the reader's PATH",
    "export": "sets a variable of the reader's shell (GLMAP_MCP: the test sets it itself)",
}
# Command heads that are slow wherever they appear, and why.
SLOW = {
    "glmap demo": "plays a whole simulated episode (tests/test_server_demo.py runs one)",
    "glmap build": "builds a map with the MiniLM embedder",
    "glmap sim tour": "renders a walk through an apartment",
    "glmap eval": "plays benchmark episodes",
    "python -m glmap_tools.bench": "benchmarks take minutes",
    "python -m glmap_tools.language": "embeds hundreds of texts with MiniLM",
    "python -m glmap_tools.worlds": "builds maps of generated apartments, embeds with MiniLM",
    "python -m glmap_tools.regression": "replays seeded episodes and tours (minutes)",
}


@dataclass(frozen=True)
class Block:
    """One fenced code block."""

    doc: str
    line: int
    lang: str
    text: str
    slow: bool
    file: str | None
    needs: str | None  # what the block needs that a test machine lacks (not run)
    venv: str | None = None  # the framework venv that runs the block

    def __str__(self) -> str:
        return f"{self.doc}:{self.line} ({self.lang or 'no language'})"


def blocks(path: Path) -> list[Block]:
    """The fenced blocks of a Markdown file with their docs-test markers."""
    out, lines = [], path.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        start, body = i, []
        i += 1
        while i < len(lines) and not lines[i].startswith("```"):
            body.append(lines[i])
            i += 1
        prev = next((ln for ln in reversed(lines[:start]) if ln.strip()), "")
        marker = MARKER.search(prev)
        out.append(
            Block(
                doc=str(path.relative_to(REPO)),
                line=start + 1,
                lang=m["lang"].lower(),
                text="\n".join(body) + "\n",
                slow=bool(marker and marker["what"] == "slow"),
                file=marker["arg"] if marker and marker["what"] == "file" else None,
                needs=marker["what"]
                if marker and marker["what"] not in ("slow", "file", "venv")
                else None,
                venv=marker["arg"] if marker and marker["what"] == "venv" else None,
            )
        )
        i += 1
    return out


def commands(text: str) -> list[list[str]]:
    """Shell commands of a block: continuation lines joined, comments and env settings dropped."""
    joined = re.sub(r"\\\n\s*", " ", text)
    out = []
    for line in joined.splitlines():
        words = shlex.split(line, comments=True)
        cmd: list[str] = []
        for word in [*words, "&&"]:
            if word != "&&":
                if cmd or not re.fullmatch(r"[A-Z_]+=\S*", word):  # drop VAR=value prefixes
                    cmd.append(word)
                continue
            if cmd:
                cmd[0] = cmd[0].removeprefix(".venv/bin/")
                out.append(["python", *cmd[1:]] if cmd[0] == "python3" else cmd)
            cmd = []
    return out


def not_run_reason(cmd: list[str]) -> str | None:
    line = " ".join(cmd)
    return next((why for head, why in NOT_RUN.items() if line.startswith(head)), None)


def is_slow(cmd: list[str]) -> bool:
    line = " ".join(cmd)
    return any(line.startswith(head) for head in SLOW)


def run_command(cmd: list[str], cwd: Path, slow: bool) -> None:
    """Run (or, for a slow block, check) one documented command; fail on a non-zero status."""
    if cmd[0] == "glmap":
        args = cmd[1:]
        if slow and not RUN_SLOW:
            cli.build_parser().parse_args(args)  # the documented options exist
            return
        status = _in(cwd, lambda: cli.main(args))
    elif cmd[:2] == ["python", "-m"]:
        module = importlib.import_module(cmd[2])
        if hasattr(module, "__path__"):  # a package: its __main__
            module = importlib.import_module(cmd[2] + ".__main__")
        args = cmd[3:]
        if slow and not RUN_SLOW:
            words = [a for a in args if re.fullmatch(r"[a-z][a-z0-9_-]*", a)][:1]
            args = [*words, "--help"]
        status = _in(cwd, lambda: module.main(args))
    else:
        pytest.fail(f"{' '.join(cmd)!r}: the docs test does not know how to run this command")
    assert status == 0, f"{' '.join(cmd)!r} exited with {status}"


def _in(cwd: Path, fn) -> int:  # type: ignore[no-untyped-def]
    old = Path.cwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            try:
                return int(fn() or 0)
            except SystemExit as exc:
                return int(exc.code or 0)
    finally:
        os.chdir(old)


def run_python(block: Block, cwd: Path) -> None:
    compile(block.text, str(block), "exec")
    if block.slow and not RUN_SLOW:
        return
    python = sys.executable
    if block.venv is not None:
        if os.environ.get("GLMAP_FRAMEWORK_VENVS") == "0":
            return
        python = str(REPO / ".ci" / "venvs" / block.venv / "bin" / "python")
        assert Path(python).exists(), f"{block} needs {python}: run bash .ci/frameworks.sh"
    script = cwd / f"block_{block.line}.py"
    script.write_text(block.text, encoding="utf-8")
    env = dict(os.environ, PYOPENGL_PLATFORM="egl", HF_HUB_OFFLINE="1")
    here = Path(sys.executable).parent
    if block.venv is None:
        env["PYTHONPATH"] = str(REPO)
        env["PATH"] = f"{here}{os.pathsep}{env.get('PATH', '')}"  # glmap-mcp
    else:  # a framework's own venv knows glmap-mcp only by the absolute path in $GLMAP_MCP
        env.pop("PYTHONPATH", None)
        paths = env.get("PATH", "").split(os.pathsep)
        env["PATH"] = os.pathsep.join(p for p in paths if p and Path(p).resolve() != here.resolve())
        env["GLMAP_MCP"] = str(here / "glmap-mcp")
    # The block's temporary folders (its maps) go under one of ours, so the servers it left
    # lingering (`--linger`, started with its maps folder) are found and stopped.
    env["TMPDIR"] = temporary = tempfile.mkdtemp(prefix="gld")
    try:
        done = subprocess.run(
            [python, str(script)], cwd=cwd, env=env, capture_output=True, text=True, timeout=900
        )
    finally:
        for pid in lingering_servers(temporary):
            os.kill(pid, signal.SIGTERM)
        shutil.rmtree(temporary, ignore_errors=True)
    assert done.returncode == 0, f"{block} failed:\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"


def check_json(block: Block, cwd: Path) -> None:
    data = json.loads(block.text)
    for name, server in data.get("mcpServers", {}).items() if isinstance(data, dict) else []:
        command = server.get("command")
        if command is not None:
            assert Path(command).is_absolute(), (
                f"{block}: server {name!r} runs {command!r}; name it by absolute path"
            )
    if block.file:
        (cwd / block.file).write_text(block.text, encoding="utf-8")


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(REPO)))
def test_every_code_block_of_the_document_runs(doc, tmp_path):
    for entry in REPO.iterdir():
        if entry.name not in (".git", "out") and not entry.name.startswith("."):
            (tmp_path / entry.name).symlink_to(entry)
    for block in blocks(doc):
        if block.needs:
            continue
        assert block.venv is None or block.lang == "python", f"{block}: venv marks python only"
        if block.lang == "json":
            check_json(block, tmp_path)
        elif block.lang == "python":
            run_python(block, tmp_path)
        elif block.lang in ("bash", "sh", "shell", "console"):
            for cmd in commands(block.text):
                if not_run_reason(cmd) is None:
                    run_command(cmd, tmp_path, block.slow or is_slow(cmd))
        else:
            assert block.lang == "text", f"{block}: give the block a language (text if not run)"


def test_the_docs_have_code_blocks_and_link_only_inside_the_repository():
    assert sum(len(blocks(d)) for d in DOCS) >= 10
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)#]+)", text):
            if not target.startswith(("http://", "https://", "mailto:")):
                resolved = (doc.parent / target).resolve()
                assert resolved.is_relative_to(REPO), f"{doc.name} links outside: {target}"
                assert resolved.exists(), f"{doc.name} links to a missing file: {target}"


def test_shell_lines_split_into_commands_without_comments_or_environment():
    text = "PYOPENGL_PLATFORM=egl .venv/bin/glmap demo   # plays\nglmap sim new \\\n  --seed 3\n"
    assert commands(text) == [["glmap", "demo"], ["glmap", "sim", "new", "--seed", "3"]]
    setup = "bash .ci/setup && X=1 .venv/bin/python -m pytest -q"
    assert commands(setup) == [["bash", ".ci/setup"], ["python", "-m", "pytest", "-q"]]
    assert is_slow(["glmap", "demo"]) and not is_slow(["glmap", "sim", "new"])


def test_help_of_every_glmap_command_shows_the_defaults():
    parser = cli.build_parser()
    sim_new = _help(parser, ["sim", "new"])
    assert "(default: 0)" in sim_new  # --seed
    assert "(default: 0.4)" in _help(parser, ["sim", "tour"])  # --step
    from glmap_tools.server.cli import build_parser as server_parser

    assert "(default: minilm)" in server_parser().format_help()


def _help(parser, path: list[str]) -> str:  # type: ignore[no-untyped-def]
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        parser.parse_args([*path, "--help"])
    return out.getvalue()


def test_loading_the_bundled_embedder_prints_no_progress_bar():
    code = (
        "from glmap_tools.language.minilm import MiniLMEmbedder; "
        "MiniLMEmbedder(); "
        "from transformers.utils import logging as l; assert l.is_progress_bar_enabled()"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO), HF_HUB_OFFLINE="1")
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Loading weights" not in done.stderr + done.stdout


@pytest.mark.anyio
@pytest.mark.parametrize("anyio_backend", ["asyncio"])
async def test_map_summary_prints_metres_rounded_not_float32_noise(tmp_path, anyio_backend):
    from mcp import Client

    from glmap_tools.server import build_server
    from tests.test_server_fixtures import config, frame_args

    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        result = await client.call_tool("map_summary", {"include_image": False})
    text = result.content[0].text
    assert '"bounds"' in text and '"floor_z"' in text
    assert not re.search(r"\d\.\d{5,}", text), text


def test_every_benchmark_prints_its_targets_through_the_shared_report():
    bench = REPO / "glmap_tools" / "bench"
    modules = [p for p in bench.glob("*.py") if not p.name.startswith("_") and p.stem != "report"]
    assert len(modules) >= 7
    for path in modules:
        assert "Report(" in path.read_text(encoding="utf-8"), f"{path.name} prints no Report"


def test_a_report_line_states_value_target_ratio_and_verdict(capsys):
    from glmap_tools.bench.report import Report

    report = Report("bench demo")
    report.check("find_instance p50", 12.34, "<=", 20.0, "ms")
    report.check("top-1, held-out half", 0.75, ">=", 0.8)
    assert report.finish() == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("bench demo: load average")
    assert lines[1] == "find_instance p50: 12.3 ms  target <= 20 ms  ratio 0.62  MET"
    assert lines[2] == "top-1, held-out half: 0.75  target >= 0.8  ratio 0.94  MISSED"
    assert lines[3].endswith("targets: 1 MET, 1 MISSED (top-1, held-out half)")
    from glmap_tools.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="op='<'"):
        report.check("x", 1.0, "<", 2.0)  # type: ignore[arg-type]
