"""The evaluation table split by episode difficulty (`glmap_tools.worlds.difficulty`).

Each episode's difficulty comes from its episode file, or is measured on load when the file
has none (older files, the built-in splits). One row per bin of `DIFFICULTY_BINS`: how many
of the selected episodes fall in it, and per agent the success rate with its bootstrap
interval and the mean SPL over the episodes of that bin it finished.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from glmap_tools.eval.stats import DEFAULT_RESAMPLES, bootstrap_mean
from glmap_tools.sim.episodes import Difficulty
from glmap_tools.worlds.difficulty import DIFFICULTY_BINS, DifficultyMeter
from glmap_tools.worlds.splits import bench_grid, bench_layout


def episode_difficulties(selected: Sequence[Any]) -> dict[str, Difficulty]:
    """episode id -> difficulty of each BenchEpisode (measured when its file has none)."""

    meters: dict[Any, DifficultyMeter] = {}
    out: dict[str, Difficulty] = {}
    for be in selected:
        d = be.episode.difficulty
        if d is None:
            path = be.layout_path
            if path not in meters:
                meters[path] = DifficultyMeter(bench_layout(path), bench_grid(path))
            d = meters[path].measure(be.episode)
        out[be.episode_id] = d
    return out


def difficulty_rows(
    records: Mapping[str, Mapping[str, Mapping[str, Any]]],
    agents: Sequence[str],
    difficulties: Mapping[str, Difficulty],
    resamples: int = DEFAULT_RESAMPLES,
) -> list[dict[str, Any]]:
    """One row per (dimension, bin): episodes in it, and per agent SR (%) with its interval,
    mean SPL (%) and the episodes it finished there."""

    rows = []
    for dimension, bin_of, bins in DIFFICULTY_BINS:
        for name in bins:
            ids = {e for e, d in difficulties.items() if bin_of(d) == name}
            row: dict[str, Any] = {"dimension": dimension, "bin": name, "episodes": len(ids)}
            for agent in agents:
                done = [r for e, r in sorted(records.get(agent, {}).items()) if e in ids]
                if not done:
                    row[agent] = None
                    continue
                sr = np.array([float(bool(r.get("success"))) for r in done]) * 100.0
                spl = [float(r["spl"]) * 100.0 for r in done if r.get("spl") is not None]
                iv = bootstrap_mean(sr, resamples=resamples)
                row[agent] = {
                    "n": len(done),
                    "sr": iv.mean,
                    "sr_low": iv.low,
                    "sr_high": iv.high,
                    "spl": float(np.mean(spl)) if spl else None,
                }
            rows.append(row)
    return rows


def difficulty_markdown(rows: Sequence[Mapping[str, Any]], agents: Sequence[str]) -> str:
    """The rows as a Markdown table: SR (%) [interval], SPL (%) and n per agent."""
    heads = [
        "Difficulty",
        "Bin",
        "Episodes",
        *(f"{a}: SR % [interval] / SPL % (n)" for a in agents),
    ]
    lines = ["| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
    for row in rows:
        cells = []
        for agent in agents:
            c = row.get(agent)
            if c is None:
                cells.append("–")
                continue
            spl = "n/a" if c["spl"] is None else f"{c['spl']:.1f}"
            cells.append(
                f"{c['sr']:.1f} [{c['sr_low']:.1f}, {c['sr_high']:.1f}] / {spl} ({c['n']})"
            )
        lines.append(
            f"| {row['dimension']} | {row['bin']} | {row['episodes']} | " + " | ".join(cells) + " |"
        )
    lines += [
        "",
        "Geodesic: shortest path to a goal; narrowest passage: the gap between obstacles on "
        "the widest way to the goal (docs/evaluation.md, Episode difficulty).",
    ]
    return "\n".join(lines) + "\n"
