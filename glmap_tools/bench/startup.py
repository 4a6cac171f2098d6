"""`python -m glmap_tools.bench startup`: how soon a fresh `glmap-mcp` answers over stdio.

Spawns the console entry as an MCP client would (default settings: the MiniLM embedder,
the renderer warm-up), writes the JSON-RPC `initialize` request at launch and
`tools/list` right after the answer, and prints the time from launch to each answer with
the target (both within 0.5 s on 2 cores; pydantic-ai's MCP toolset waits 5 s) and MET or
MISSED. Then it times the first find_instance, which waits for the embedder (<= 3 s). A
second launch per run times a stateless 2026-07-28 client (`server/discover` and
`tools/list` sent at once, as pydantic-ai's fastmcp transport does). The answers come from
the prepared handshake file when it is there (docs/mcp.md, Start-up).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from queue import Empty, Queue
from typing import Any

from glmap_tools.bench._args import positive_seconds, whole
from glmap_tools.bench.report import Report
from glmap_tools.server.handshake import (
    MODERN_VERSIONS,
    PreparedAnswers,
    answers_path,
    opening_requests,
    prepare_handshake,
    source_stamp,
)

INITIALIZE_TARGET_S = 0.5
TOOLS_LIST_TARGET_S = 0.5
FIRST_FIND_TARGET_S = 3.0  # the text embedder loads in the background meanwhile
PROTOCOL = "2025-11-25"  # the dated protocol clients of mcp 1.x (and 2.x in legacy mode) send
STATELESS_PROTOCOL = "2026-07-28"


def server_command() -> list[str]:
    """`glmap-mcp` beside this Python (the installed console script), else the module."""
    script = shutil.which("glmap-mcp", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "glmap_tools.server"]


class StdioPeer:
    """A spawned server spoken to in newline-delimited JSON-RPC over its stdin/stdout."""

    def __init__(self, command: list[str], env: dict[str, str]) -> None:
        self.started = time.perf_counter()
        self.proc = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            text=True,
        )
        self.lines: Queue[str] = Queue()
        self.stderr: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()
        threading.Thread(target=self._pump_err, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line)
        self.lines.put("")

    def _pump_err(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.stderr.append(line)

    def send(self, message: dict[str, Any]) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(message) + "\n")
        self.proc.stdin.flush()

    def answer(self, request_id: int, timeout: float) -> tuple[dict[str, Any], float]:
        """(the response to `request_id`, seconds since launch); notifications are skipped."""
        deadline = time.perf_counter() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(deadline - time.perf_counter(), 0.01))
            except Empty:
                raise TimeoutError(f"no answer to request {request_id} in {timeout} s") from None
            if not line:
                raise RuntimeError("the server exited:\n" + "".join(self.stderr[-20:]))
            message = json.loads(line)
            if message.get("id") == request_id:
                return message, time.perf_counter() - self.started

    def open(
        self, version: str, timeout: float, client: str = "bench-startup"
    ) -> tuple[tuple[dict[str, Any], float], tuple[dict[str, Any], float]]:
        """Open a session in `version` as a client does and list the tools: ((opening answer,
        seconds since launch), (tools/list answer, seconds)). A handshake-era client waits
        for the `initialize` answer before it sends more; a stateless one sends both."""

        first, *rest = opening_requests(version, client)
        self.send(first)
        if version not in MODERN_VERSIONS:
            opened = self.answer(1, timeout)
            for message in rest:
                self.send(message)
            return opened, self.answer(2, timeout)
        for message in rest:
            self.send(message)
        return self.answer(1, timeout), self.answer(2, timeout)

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=20)


def measure(command: list[str], extra_args: list[str], timeout: float) -> dict[str, float]:
    """Seconds from launch to initialize, to tools/list and to the first find_instance."""
    env = dict(os.environ, HF_HUB_OFFLINE="1", TRANSFORMERS_OFFLINE="1")
    with tempfile.TemporaryDirectory() as maps:
        peer = StdioPeer([*command, "--maps-dir", maps, *extra_args], env)
        try:
            (_, t_init), (listed, t_list) = peer.open(PROTOCOL, timeout)
            cpu_list = process_cpu_seconds(peer.proc.pid)
            tools = len(listed["result"]["tools"])
            call = {"name": "find_instance", "arguments": {"query": "a chair"}}
            peer.send({"jsonrpc": "2.0", "id": 3, "method": "tools/call", "params": call})
            _, t_find = peer.answer(3, timeout)
        finally:
            peer.close()
    return {
        "initialize": t_init,
        "tools/list": t_list,
        "cpu": cpu_list,
        "find_instance": t_find,
        "tools": tools,
    }


def measure_stateless(command: list[str], extra_args: list[str], timeout: float) -> float:
    """Seconds from launch to the tools/list answer of a 2026-07-28 (stateless) client, which
    sends `server/discover` and `tools/list` at once (pydantic-ai through fastmcp does)."""
    env = dict(os.environ, HF_HUB_OFFLINE="1", TRANSFORMERS_OFFLINE="1")
    with tempfile.TemporaryDirectory() as maps:
        peer = StdioPeer([*command, "--maps-dir", maps, *extra_args], env)
        try:
            _, (_, t_list) = peer.open(STATELESS_PROTOCOL, timeout)
        finally:
            peer.close()
    return t_list


def prepared_versions() -> set[str]:
    """The protocol versions this installation has prepared handshake answers for."""

    return set(PreparedAnswers(answers_path(), source_stamp()).complete())


def process_cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process's main thread so far (Linux /proc), else NaN.

    On a busy machine the wall time to an answer mostly measures the other processes; the
    CPU time the server's main thread (imports, then the event loop answering) spent is
    close to what the wall time would be on an idle machine. The background threads
    (embedder, kernels) are left out: on two idle cores they run beside it.
    """
    try:
        fields = Path(f"/proc/{pid}/task/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main(argv: list[str] | None = None) -> int:
    args = _arguments(argv)
    report = Report("bench startup")
    command = shlex.split(args.server_command) if args.server_command else server_command()
    report.info(f"glmap-mcp over stdio: {' '.join([*command, *args.server_args])}")
    _prepare_answers(report, args.unprepared)
    runs = []
    for i in range(args.runs):
        r = measure(command, args.server_args, args.timeout)
        r["stateless"] = measure_stateless(command, args.server_args, args.timeout)
        runs.append(r)
        report.info(
            f"run {i + 1}: initialize {r['initialize']:.2f} s, tools/list {r['tools/list']:.2f} s "
            f"({r['tools']:.0f} tools; main-thread CPU by then {r['cpu']:.2f} s), first "
            f"find_instance {r['find_instance']:.2f} s; a {STATELESS_PROTOCOL} client's "
            f"tools/list {r['stateless']:.2f} s"
        )
    worst = f"worst of {len(runs)} launches"
    report.check(
        f"initialize after launch, {worst}",
        max(r["initialize"] for r in runs),
        "<=",
        INITIALIZE_TARGET_S,
        "s",
    )
    report.check(
        f"tools/list after launch, {worst}",
        max(r["tools/list"] for r in runs),
        "<=",
        TOOLS_LIST_TARGET_S,
        "s",
    )
    report.check(
        f"tools/list after launch, {STATELESS_PROTOCOL} client (server/discover), {worst}",
        max(r["stateless"] for r in runs),
        "<=",
        TOOLS_LIST_TARGET_S,
        "s",
    )
    report.check(
        f"server main-thread CPU until tools/list, {worst} (~ wall time when idle)",
        max(r["cpu"] for r in runs),
        "<=",
        TOOLS_LIST_TARGET_S,
        "s",
    )
    report.check(
        f"first find_instance after launch (waits for the embedder), {worst}",
        max(r["find_instance"] for r in runs),
        "<=",
        FIRST_FIND_TARGET_S,
        "s",
    )
    return report.finish()


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    """The command line of `python -m glmap_tools.bench startup`."""
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench startup")
    parser.add_argument("--runs", type=whole(1, 100), default=3, help="fresh launches to time")
    parser.add_argument(
        "--timeout", type=positive_seconds(3600), default=300.0, help="seconds per answer"
    )
    parser.add_argument(
        "--unprepared",
        action="store_true",
        help="do not prepare the handshake answers first when this installation has none",
    )
    parser.add_argument(
        "--server-command", default="", help="the server command (default: glmap-mcp here)"
    )
    parser.add_argument(
        "server_args", nargs="*", help="extra glmap-mcp arguments (after --), e.g. -- --no-warm-up"
    )
    return parser.parse_args(argv)


def _prepare_answers(report: Report, unprepared: bool) -> None:
    """Prepare the handshake answers when this installation has none (as `glmap-mcp
    --prepare` does at setup), unless `unprepared`: then run 1 times their making."""
    if not {PROTOCOL, STATELESS_PROTOCOL} <= prepared_versions():
        if unprepared:
            report.info(
                "no prepared handshake answers for this installation (its sources changed "
                "since they were kept): run 1 answers through the SDK and keeps them"
            )
        else:
            report.info(
                "no prepared handshake answers for this installation (its sources changed "
                "since they were kept): preparing them first, as `glmap-mcp --prepare` does at "
                "setup (--unprepared times that first launch instead)"
            )
            prepare_handshake()
