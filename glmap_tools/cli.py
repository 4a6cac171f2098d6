"""The `glmap` console script: one subcommand per user-facing job."""

from __future__ import annotations

import argparse
import importlib
import sys

from glmap_tools.cli_format import show_defaults
from glmap_tools.errors import GLMapError
from glmap_tools.launch_env import set_thread_defaults

# Each module provides `register(subparsers)`, adding its subcommand(s) with a `func`.
COMMAND_MODULES = [
    "glmap_tools.ingest.cli",
    "glmap_tools.worlds.cli",
    "glmap_tools.server.demo",
    "glmap_tools.language.cli",
    "glmap_tools.eval.cli",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="glmap", description="Build and query Gaussian-Language Maps (GLMap)."
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return show_defaults(parser)


def main(argv: list[str] | None = None) -> int:
    set_thread_defaults()
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except GLMapError as exc:
        print(f"glmap {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
