"""Per-agent means with bootstrap intervals, paired differences, and their Markdown tables."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from glmap_tools.eval.stats import (
    DEFAULT_CONFIDENCE,
    DEFAULT_RESAMPLES,
    Interval,
    bootstrap_mean,
    paired_difference,
)

# Imports inside functions stay there: gymnasium load on first use: `glmap` imports every command
# module to build its parser.


@dataclass(frozen=True)
class Metric:
    """One column: the record key, its heading and the factor it is shown with."""

    key: str
    heading: str
    scale: float = 1.0
    digits: int = 1


METRICS = (
    Metric("success", "SR (%)", 100.0),
    Metric("spl", "SPL (%)", 100.0),
    Metric("distance_to_goal", "Dist. to goal (m)", 1.0, 2),
    Metric("steps", "Steps"),
    Metric("tool_calls", "Tool calls"),
)
PAIRED = METRICS[:3]


@dataclass(frozen=True)
class Summary:
    """The numbers behind the tables.

    Attributes:
        rows: agent -> metric key -> Interval (absent when the agent has no finite value).
        episodes: agent -> episodes finished.
        paired: (reference agent, other agent) -> metric key -> Interval of reference - other
            over the episodes both finished.
        resamples, confidence, seed: the bootstrap's settings.
        outcomes: agent -> how its episodes ended (`glmap_tools.sim.outcome.OUTCOMES`) ->
            episodes; records without an outcome are left out.
    """

    rows: dict[str, dict[str, Interval]]
    episodes: dict[str, int]
    paired: dict[tuple[str, str], dict[str, Interval]]
    resamples: int
    confidence: float
    seed: int
    outcomes: dict[str, dict[str, int]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        def iv(i: Interval) -> dict[str, float]:
            return {"mean": i.mean, "low": i.low, "high": i.high, "n": i.n}

        return {
            "bootstrap": {
                "method": "percentile",
                "resamples": self.resamples,
                "confidence": self.confidence,
                "seed": self.seed,
            },
            "agents": {
                a: {"episodes": self.episodes[a], **{k: iv(v) for k, v in m.items()}}
                for a, m in self.rows.items()
            },
            "paired": [
                {"reference": r, "other": o, **{k: iv(v) for k, v in m.items()}}
                for (r, o), m in self.paired.items()
            ],
            "outcomes": self.outcomes,
        }


def _values(records: Mapping[str, Mapping[str, Any]], key: str) -> dict[str, float]:
    """episode id -> finite value of `key` (booleans as 0/1; null and inf left out), in
    episode-id order, so an interval does not depend on the order results were read in."""
    out = {}
    for eid in sorted(records):
        v = records[eid].get(key)
        if v is None:
            continue
        v = float(v)
        if math.isfinite(v):
            out[eid] = v
    return out


def summarize(
    records: Mapping[str, Mapping[str, Mapping[str, Any]]],
    agents: Sequence[str],
    *,
    reference: str | None = None,
    resamples: int = DEFAULT_RESAMPLES,
    confidence: float = DEFAULT_CONFIDENCE,
    seed: int = 0,
) -> Summary:
    """Means and intervals of every metric per agent, and `reference` minus each other agent.

    Args:
        records: agent -> episode id -> episode record (EpisodeResult fields).
        agents: the agents to report, in table order.
        reference: the agent the others are compared with (default: the first).
    """
    reference = reference or agents[0]
    kw: dict[str, Any] = {"resamples": resamples, "confidence": confidence, "seed": seed}
    rows: dict[str, dict[str, Interval]] = {}
    for agent in agents:
        rows[agent] = {}
        for m in METRICS:
            vals = list(_values(records.get(agent, {}), m.key).values())
            if vals:
                rows[agent][m.key] = bootstrap_mean(np.array(vals) * m.scale, **kw)
    paired: dict[tuple[str, str], dict[str, Interval]] = {}
    for other in agents:
        if other == reference:
            continue
        diffs: dict[str, Interval] = {}
        for m in PAIRED:
            a = _values(records.get(reference, {}), m.key)
            b = _values(records.get(other, {}), m.key)
            common = sorted(set(a) & set(b))
            if common:
                va = np.array([a[e] for e in common]) * m.scale
                vb = np.array([b[e] for e in common]) * m.scale
                diffs[m.key] = paired_difference(va, vb, **kw)
        paired[(reference, other)] = diffs
    episodes = {a: len(records.get(a, {})) for a in agents}
    outcomes = {a: _outcomes(records.get(a, {})) for a in agents}
    return Summary(rows, episodes, paired, resamples, confidence, seed, outcomes)


def _outcomes(records: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
    """How many episodes ended each way (the failure taxonomy), in the taxonomy's order."""
    from glmap_tools.sim.outcome import OUTCOMES

    counts = dict.fromkeys(OUTCOMES, 0)
    for record in records.values():
        kind = record.get("outcome")
        if kind in counts:
            counts[kind] += 1
    return counts if any(counts.values()) else {}


def _cell(i: Interval | None, digits: int, sign: bool = False) -> str:
    if i is None:
        return "n/a"
    f = f"{{:{'+' if sign else ''}.{digits}f}}"
    return f"{f.format(i.mean)} [{f.format(i.low)}, {f.format(i.high)}]"


def markdown(summary: Summary) -> str:
    """The agents table and the paired-difference table, with a line on the bootstrap."""
    heads = ["Agent", "Episodes", *(m.heading for m in METRICS)]
    lines = ["| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
    for agent, row in summary.rows.items():
        cells = [_cell(row.get(m.key), m.digits) for m in METRICS]
        lines.append(f"| {agent} | {summary.episodes[agent]} | " + " | ".join(cells) + " |")
    if summary.paired:
        heads = [
            "Paired difference",
            "Episodes",
            *(f"Δ {m.heading.replace('(%)', '(points)')}" for m in PAIRED),
        ]
        lines += ["", "| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
        for (ref, other), diffs in summary.paired.items():
            n = max((i.n for i in diffs.values()), default=0)
            cells = [_cell(diffs.get(m.key), m.digits, sign=True) for m in PAIRED]
            lines.append(f"| {ref} − {other} | {n} | " + " | ".join(cells) + " |")
    if any(summary.outcomes.values()):
        kinds = next(iter(o for o in summary.outcomes.values() if o))
        heads = ["How episodes ended", *kinds]
        lines += ["", "| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
        for agent, counts in summary.outcomes.items():
            if counts:
                lines.append(f"| {agent} | " + " | ".join(str(counts[k]) for k in kinds) + " |")
    pct = round(summary.confidence * 100)
    lines += [
        "",
        f"Mean [{pct}% interval]: percentile bootstrap over episodes, {summary.resamples} "
        f"resamples, seed {summary.seed}; paired rows resample the episodes both agents "
        "finished. Dist. to goal leaves out episodes that ended where the goal is unreachable.",
    ]
    return "\n".join(lines) + "\n"
