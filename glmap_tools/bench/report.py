"""One way for every benchmark to print a figure against its target: MET or MISSED.

Usage::

    from glmap_tools.bench.report import Report

    report = Report("bench mcp")  # prints the title, CPU count and load average
    report.check("find_instance p50, 10k instances", p50_ms, "<=", 20.0, "ms")
    report.check("top-1, held-out half", top1, ">=", 0.8)
    report.info("map built in 3.2 s")  # a figure with no target
    return report.finish()  # prints the load average again and "targets: 2 MET, 0 MISSED"

Each checked line reads ``<name>: <value> <unit>  target <op> <target> <unit>  ratio <r>  MET``,
so a reader (or a grep for ``MISSED``) finds every miss the same way in every benchmark.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Literal

from glmap_tools.errors import InvalidInputError

__all__ = ["Check", "Report", "load_average"]

Op = Literal["<=", ">="]


def load_average() -> str:
    """The 1-minute load average and CPU count, e.g. 'load average 1.23 on 2 CPUs'."""
    try:
        load = f"{os.getloadavg()[0]:.2f}"
    except OSError:  # not available on this platform
        load = "n/a"
    return f"load average {load} on {os.cpu_count()} CPUs"


def _fmt(x: float) -> str:
    """A figure with about three significant digits, no exponent for everyday sizes."""
    if x == 0 or 0.01 <= abs(x) < 1e6:
        return f"{x:.3g}" if abs(x) < 100 else f"{x:.0f}"
    return f"{x:.3g}"


@dataclass(frozen=True)
class Check:
    """One measured figure against its target.

    Attributes:
        name: what was measured, e.g. 'find_instance p50, 10k instances'.
        value: the measured figure.
        op: '<=' (lower is better) or '>=' (higher is better).
        target: the bound the figure has to meet.
        unit: unit of value and target ('' for a ratio or a count).
    """

    name: str
    value: float
    op: Op
    target: float
    unit: str = ""

    @property
    def met(self) -> bool:
        return self.value <= self.target if self.op == "<=" else self.value >= self.target

    @property
    def ratio(self) -> float:
        """value / target (<= 1 is good for '<=', >= 1 is good for '>=')."""
        return self.value / self.target if self.target else float("inf")

    def line(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        verdict = "MET" if self.met else "MISSED"
        return (
            f"{self.name}: {_fmt(self.value)}{unit}  target {self.op} {_fmt(self.target)}{unit}"
            f"  ratio {self.ratio:.2f}  {verdict}"
        )


@dataclass
class Report:
    """Collects a benchmark's checks and prints each as it is made.

    Args:
        title: the benchmark's name, printed first with the CPU count and load average.
        quiet: collect without printing (for tests and callers that print themselves).
    """

    title: str
    quiet: bool = False
    checks: list[Check] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._print(f"{self.title}: {load_average()}")

    def _print(self, text: str) -> None:
        if not self.quiet:
            print(text, flush=True)

    def check(self, name: str, value: float, op: Op, target: float, unit: str = "") -> Check:
        """Record and print one figure against its target; returns the Check."""
        if op not in ("<=", ">="):
            raise InvalidInputError(
                f"op={op!r}: use '<=' (lower is better) or '>=' (higher is better)."
            )
        c = Check(name, float(value), op, float(target), unit)
        self.checks.append(c)
        self._print(c.line())
        return c

    def info(self, text: str) -> None:
        """Print a figure or note that has no target."""
        self._print(text)

    def finish(self) -> int:
        """Print the load average and the MET/MISSED counts; return 0 (the exit status).

        A missed target is a finding to report, not a crash, so the status stays 0.
        """
        met = sum(c.met for c in self.checks)
        missed = [c.name for c in self.checks if not c.met]
        tail = f" ({'; '.join(missed)})" if missed else ""
        self._print(f"{load_average()}; targets: {met} MET, {len(missed)} MISSED{tail}")
        return 0
