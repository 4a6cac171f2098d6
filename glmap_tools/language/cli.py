"""`glmap llm`: check a model server, and serve or record Ollama transcripts.

    glmap llm check --model qwen3:8b                  # is Ollama up, is the model pulled?
    glmap llm replay tests/cassettes/nav_scores.jsonl --port 11500
    glmap llm record out/my.jsonl --upstream http://127.0.0.1:11434 --port 11500

`replay` and `record` serve an Ollama-compatible API on 127.0.0.1 until interrupted; point
any command's --ollama-host (or $OLLAMA_HOST) at the printed URL.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import threading
from typing import Any

from glmap_tools.language.llm import OllamaClient
from glmap_tools.language.ollama_replay import OllamaReplayServer


def _check(args: argparse.Namespace) -> int:

    info = OllamaClient(args.model, host=args.ollama_host, retries=0).check()
    print(json.dumps(info, indent=1))
    return 0


def _serve(args: argparse.Namespace, upstream: str | None) -> int:

    stop = threading.Event()
    server = OllamaReplayServer(
        args.cassette,
        upstream=upstream,
        port=args.port,
        record_command=f"glmap llm record {args.cassette} --upstream <ollama url>",
    )
    with server:
        mode = f"recording from {upstream}" if upstream else "replaying"
        print(f"{mode} {args.cassette} at {server.host} (Ctrl-C to stop)", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            stop.wait(args.seconds if args.seconds > 0 else None)
    if upstream:
        print(f"wrote {len(server.cassette.exchanges)} exchanges to {args.cassette}")
    return 0


def register(subparsers: Any) -> None:
    fmt = argparse.ArgumentDefaultsHelpFormatter
    p = subparsers.add_parser(
        "llm", help="check a model server; serve or record Ollama transcripts", formatter_class=fmt
    )
    sub = p.add_subparsers(dest="llm_command", metavar="ACTION", required=True)
    c = sub.add_parser(
        "check", help="is Ollama reachable and the model pulled?", formatter_class=fmt
    )
    c.add_argument("--model", default="qwen3:8b", help="Ollama model tag")
    c.add_argument("--ollama-host", default=None, help="server URL ($OLLAMA_HOST or local)")
    c.set_defaults(func=_check)
    for name, helptext in (
        ("replay", "serve a recording as an Ollama API on 127.0.0.1"),
        ("record", "proxy a live Ollama on 127.0.0.1 and record every exchange"),
    ):
        s = sub.add_parser(name, help=helptext, formatter_class=fmt)
        s.add_argument("cassette", help="the cassette file (JSON Lines)")
        s.add_argument("--port", type=int, default=11500, help="port on 127.0.0.1 (0 = any)")
        s.add_argument("--seconds", type=float, default=0, help="stop after this long (0 = never)")
        if name == "record":
            s.add_argument("--upstream", required=True, help="the live Ollama URL")
            s.set_defaults(func=lambda a: _serve(a, a.upstream))
        else:
            s.set_defaults(func=lambda a: _serve(a, None))
