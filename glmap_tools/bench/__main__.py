"""Dispatch `python -m glmap_tools.bench NAME [args]` to `glmap_tools.bench.NAME.main`."""

from __future__ import annotations

import importlib
import pkgutil
import sys

import glmap_tools.bench as bench_pkg
from glmap_tools.errors import GLMapError, did_you_mean
from glmap_tools.launch_env import set_thread_defaults


def main(argv: list[str] | None = None) -> int:
    set_thread_defaults()
    argv = list(sys.argv[1:] if argv is None else argv)
    names = sorted(m.name for m in pkgutil.iter_modules(bench_pkg.__path__) if m.name[0] != "_")
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: python -m glmap_tools.bench {" + ",".join(names) + "} [args]")
        return 0 if argv else 2
    name = argv[0].replace("-", "_")  # `nav-core` runs bench/nav_core.py
    if name not in names:
        print(
            f"unknown benchmark {name!r}.{did_you_mean(name, names)} Choose from {names}.",
            file=sys.stderr,
        )
        return 2
    module = importlib.import_module(f"glmap_tools.bench.{name}")
    try:
        return int(module.main(argv[1:]) or 0)
    except GLMapError as exc:  # bad arguments or inputs: the message, not a traceback
        print(f"bench {name}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
