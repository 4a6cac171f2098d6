"""`glmap eval compare A B`: two navigation result folders side by side.

For prompt experiments (the same episodes with two prompt folders) and any A/B of
settings: success rate and SPL per agent with bootstrap intervals, the paired difference
on the episodes both folders finished, and tool calls and model tokens per episode.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.eval.stats import bootstrap_mean, paired_difference


def load_folder(folder: Path) -> tuple[dict[str, Any], dict[str, dict[str, dict[str, Any]]]]:
    """(eval.json settings, agent -> episode id -> record) of a results folder."""
    config_file = folder / "eval.json"
    if not config_file.is_file():
        raise InvalidInputError(
            f"{folder} is not a glmap eval results folder (no eval.json); give the --out "
            "folder of a `glmap eval objectnav|instnav` run."
        )
    config = json.loads(config_file.read_text(encoding="utf-8"))
    records: dict[str, dict[str, dict[str, Any]]] = {}
    for path in sorted((folder / "episodes").glob("*/*.json")):
        r = json.loads(path.read_text(encoding="utf-8"))
        records.setdefault(r["agent"], {})[r["episode_id"]] = r
    return config, records


def _settings(config: dict[str, Any]) -> dict[str, Any]:
    return dict(config.get("config", config))


def compare(a: Path, b: Path, resamples: int = 2000) -> str:
    """The Markdown table comparing folders `a` and `b`."""

    ca, ra = load_folder(a)
    cb, rb = load_folder(b)

    def cell(i: Any) -> str:
        return f"{i.mean:.3f} [{i.low:.3f}, {i.high:.3f}]"

    sa, sb = _settings(ca), _settings(cb)
    differ = sorted(k for k in set(sa) | set(sb) if sa.get(k) != sb.get(k))
    lines = [
        f"A = {a}, B = {b}; settings that differ: "
        + (", ".join(f"{k} ({sa.get(k)!r} vs {sb.get(k)!r})" for k in differ) or "none"),
        "",
        "| agent | n | SR A | SR B | SR B-A (paired) | SPL A | SPL B | calls/ep A | calls/ep B "
        "| tokens/ep A | tokens/ep B |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for agent in sorted(set(ra) & set(rb)):
        common = sorted(set(ra[agent]) & set(rb[agent]))
        if not common:
            continue

        def col(rs: dict[str, dict[str, Any]], key: str, ids: list[str] = common) -> np.ndarray:
            return np.array([float(rs[e].get(key) or 0.0) for e in ids])

        sr_a, sr_b = col(ra[agent], "success"), col(rb[agent], "success")
        calls = (
            f"{col(ra[agent], 'tool_calls').mean():.1f} | {col(rb[agent], 'tool_calls').mean():.1f}"
        )
        d = paired_difference(sr_b, sr_a, resamples=resamples)
        lines.append(
            f"| {agent} | {len(common)} | {cell(bootstrap_mean(sr_a, resamples=resamples))} | "
            f"{cell(bootstrap_mean(sr_b, resamples=resamples))} | {cell(d)} | "
            f"{col(ra[agent], 'spl').mean():.3f} | {col(rb[agent], 'spl').mean():.3f} | "
            f"{calls} | "
            f"{col(ra[agent], 'tokens').mean():.0f} | {col(rb[agent], 'tokens').mean():.0f} |"
        )
    if len(lines) == 4:
        raise InvalidInputError(
            f"{a} and {b} share no (agent, episode) pair; run the same episodes in both."
        )
    return "\n".join(lines) + "\n"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("a", type=Path, help="results folder A (the baseline)")
    p.add_argument("b", type=Path, help="results folder B")
    p.add_argument("--resamples", type=int, default=2000, help="bootstrap resamples")


def run_cli(args: argparse.Namespace) -> int:
    print(compare(args.a, args.b, args.resamples))
    return 0
