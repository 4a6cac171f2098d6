"""The `glmap` console script: one subcommand per user-facing job."""

from __future__ import annotations

import argparse
import importlib
import sys

from glmap_tools.errors import GLMapError

# Each module provides `register(subparsers)`, adding its subcommand(s) with a `func`.
COMMAND_MODULES = [
    "glmap_tools.ingest.cli",
    "glmap_tools.sim.cli",
    "glmap_tools.server.demo",
    "glmap_tools.language.cli",
    "glmap_tools.eval.cli",
]


class HelpWithDefaults(argparse.RawDescriptionHelpFormatter):
    """--help text that ends each option's line with its default, when it has one."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if default is None or default is False or default == [] or default == argparse.SUPPRESS:
            return text
        if "default" in text.lower():  # the help already says it
            return text
        return f"{text} (default: %(default)s)".strip()


def show_defaults(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Make `parser` and every subcommand parser under it print defaults in --help."""
    parser.formatter_class = HelpWithDefaults
    for action in parser._actions:
        has_default = action.default is not None and action.default is not False
        if action.help is None and action.option_strings and has_default:
            action.help = "(default: %(default)s)"  # argparse skips options without help
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                show_defaults(sub)
    return parser


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="glmap", description="Build and query Gaussian-Language Maps (GLMap)."
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return show_defaults(parser)


def main(argv: list[str] | None = None) -> int:
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
