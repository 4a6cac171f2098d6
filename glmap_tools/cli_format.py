"""--help formatting shared by every console command (`glmap`, `glmap-mcp`, the benchmarks)."""

from __future__ import annotations

import argparse


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
