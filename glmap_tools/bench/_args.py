"""argparse types of the benchmarks' options: a value out of range is one usage error that
names it and the range, before anything runs."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

MAX_SIDE = 4096  # pixels, as the simulator's cameras


def whole(lo: int, hi: int) -> Callable[[str], int]:
    """A whole number in lo..hi."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a whole number; give one in {lo}..{hi}"
            ) from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{value} is not in {lo}..{hi}")
        return value

    return parse


def positive_seconds(hi: float) -> Callable[[str], float]:
    """Seconds in (0, hi]."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
        if not (math.isfinite(value) and 0 < value <= hi):
            raise argparse.ArgumentTypeError(f"{text} s is not in (0, {hi:g}]")
        return value

    return parse


def image_size(text: str) -> str:
    """WIDTHxHEIGHT, each side 1..4096 pixels (kept as the text the benchmark parses)."""
    w, sep, h = text.lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit() and 1 <= int(w) <= MAX_SIDE >= int(h) >= 1):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not WIDTHxHEIGHT with each side in 1..{MAX_SIDE}, e.g. 320x240"
        )
    return text


def existing_file(text: str) -> Path:
    """A file that exists."""
    path = Path(text).expanduser()
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r} is not a file")
    return path
