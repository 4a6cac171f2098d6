"""`python -m glmap_tools.bench connections`: half-sent HTTP requests against glmap-mcp.

Spawns `glmap-mcp --transport streamable-http` on 127.0.0.1 (hashing embedder, a token in
the environment), opens `--stalled` connections that send the start of a request without a
token and stall, then prints the file descriptors the server holds, whether a client with
the token still gets tools/list answered (and how fast), and the descriptors held once the
request deadline has passed. Targets: the server holds at most its connection cap (64)
plus its own files, and the authorised call is answered within 5 s.
"""

from __future__ import annotations

import argparse
import os
import shlex
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from urllib.parse import urlparse

import anyio
import httpx2
from mcp import Client
from mcp.client.streamable_http import streamable_http_client

from glmap_tools.bench._args import positive_seconds, whole
from glmap_tools.bench.report import Report

TOKEN = "bench-connections-token"
ANSWER_TARGET_S = 5.0
CAP = 64
OWN_FILES = 64  # descriptors a serving process holds anyway (libraries, pipes, sockets)


def open_fds(pid: int) -> int:
    """Descriptors the process holds (Linux /proc); -1 elsewhere."""
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return -1


def authorised_call(url: str, timeout: float) -> float:
    """Seconds for a tools/list over a fresh connection with the token (inf on failure)."""

    async def call() -> None:
        http = httpx2.AsyncClient(
            headers={"Authorization": f"Bearer {TOKEN}"}, timeout=httpx2.Timeout(timeout)
        )
        with anyio.fail_after(timeout):
            async with Client(
                streamable_http_client(url, http_client=http), mode="legacy"
            ) as client:
                await client.list_tools()

    start = time.perf_counter()
    try:
        anyio.run(call)
    except Exception:  # a refused, reset or timed-out call: the figure says it failed
        return float("inf")
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:

    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench connections")
    parser.add_argument(
        "--stalled", type=whole(1, 10_000), default=300, help="half-sent requests to open"
    )
    parser.add_argument(
        "--timeout", type=positive_seconds(3600), default=30.0, help="seconds for the call"
    )
    parser.add_argument(
        "--server-command", default="", help="the server command (default: this Python)"
    )
    args = parser.parse_args(argv)
    report = Report("bench connections")
    command = (
        shlex.split(args.server_command)
        if args.server_command
        else [sys.executable, "-m", "glmap_tools.server"]
    )
    with tempfile.TemporaryDirectory() as maps:
        command += ["--transport", "streamable-http", "--port", "0", "--no-warm-up"]
        command += ["--embedder", "hashing", "--maps-dir", str(Path(maps))]
        env = dict(os.environ, GLMAP_MCP_TOKEN=TOKEN)
        proc = subprocess.Popen(command, env=env, stderr=subprocess.PIPE, text=True)
        stalled: list[socket.socket] = []
        try:
            assert proc.stderr is not None
            url = next(
                (line.split()[-1] for line in proc.stderr if line.startswith("glmap-mcp: serv")),
                "",
            )
            if not url:
                raise RuntimeError("glmap-mcp did not start")
            log_lines: list[str] = []
            threading.Thread(target=log_lines.extend, args=(proc.stderr,), daemon=True).start()
            target = urlparse(url)
            base = open_fds(proc.pid)
            for _ in range(args.stalled):
                sock = socket.create_connection((target.hostname, target.port), timeout=5)
                sock.sendall(b"POST /mcp HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 99\r\n")
                stalled.append(sock)
            time.sleep(1.0)
            held = open_fds(proc.pid)
            report.info(f"server: {' '.join(command[:3])}; {base} descriptors before")
            report.check(
                f"server descriptors with {args.stalled} half-sent requests open",
                held,
                "<=",
                CAP + OWN_FILES,
            )
            seconds = authorised_call(url, args.timeout)
            report.check("tools/list with the token meanwhile", seconds, "<=", ANSWER_TARGET_S, "s")
            time.sleep(12.0)
            report.info(f"server descriptors 12 s later: {open_fds(proc.pid)}")
            report.info(f"server log lines meanwhile: {len(log_lines)}")
        finally:
            for sock in stalled:
                sock.close()
            proc.terminate()
            proc.wait(timeout=30)
    return report.finish()
