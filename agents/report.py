"""The episode report: Markdown and HTML, step by step with frames and value maps.

Written beside the trace (`trace.jsonl`) by `agents.runner.run_episode`: the result, the
first view, then every step the agent fetched images for (its egocentric frame and the
value map with frontiers, the chosen waypoint and the planned and travelled paths), and a
table of the actions, subsampled to at most `MAX_ROWS` rows.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from agents.objectnav import Play, StepRecord

MAX_ROWS = 80
LEGEND = (
    "Each step shows the agent's view, then the value map from above: the heat is the value "
    "H of paper Eq. 7 (colour bar on the right), light grey never observed, white seen free, "
    "dark grey obstacles, coloured cells instance footprints with their ids; the red arrow "
    "is the agent, cyan circles frontiers, the magenta cross the waypoint and the green line "
    "the planned path. Axes in metres."
)
RESULT_KEYS = ("status", "success", "spl", "distance_to_goal", "steps", "path_length", "collisions")


def _waypoint(s: StepRecord) -> str:
    w = s.waypoint
    if not w:
        return ""
    xy = w.get("xy")
    where = f" ({xy[0]:.2f}, {xy[1]:.2f})" if xy else ""
    unit = f" unit {w['unit_id']}" if w.get("unit_id") is not None else ""
    return f"{w.get('kind', '')}{where}{unit}"


def _rows(steps: list[StepRecord]) -> list[StepRecord]:
    if len(steps) <= MAX_ROWS:
        return steps
    every = -(-len(steps) // MAX_ROWS)
    return [s for i, s in enumerate(steps) if i % every == 0 or s.images or i == len(steps) - 1]


def write_report(
    out_dir: Path, title: str, result: dict[str, Any], play: Play, start_images: list[str]
) -> tuple[Path, Path]:
    """Write `report.md` and `report.html` in `out_dir`; return their paths."""
    facts = {k: play.final.get(k) for k in RESULT_KEYS if k in play.final}
    facts.update({k: result[k] for k in ("tool_calls", "wall_s", "seed") if k in result})
    goal = play.start.get("goal", "")
    md = [f"# {title}", "", f"Goal: **{goal}**", "", "```json", json.dumps(facts), "```", ""]
    md += [LEGEND, ""]
    md += ["## Start", ""] + [f"![start view]({img})" for img in start_images] + [""]
    for s in play.steps:
        if not s.images:
            continue
        md += [
            f"## Step {s.step}: {s.action}",
            "",
            f"At ({s.position[0]:.2f}, {s.position[1]:.2f}), heading {s.heading_deg:.0f}°. "
            f"Waypoint: {_waypoint(s) or '-'}. {s.reason}",
            "",
        ]
        md += [f"![step {s.step} image {k + 1}]({img})" for k, img in enumerate(s.images)] + [""]
    md += ["## Actions", "", "| step | action | position | heading | waypoint | reason |"]
    md += ["|---|---|---|---|---|---|"]
    for s in _rows(play.steps):
        md.append(
            f"| {s.step} | {s.action} | ({s.position[0]:.2f}, {s.position[1]:.2f}) | "
            f"{s.heading_deg:.0f} | {_waypoint(s)} | {s.reason.replace('|', '/')} |"
        )
    md_path = out_dir / "report.md"
    md_path.write_text("\n".join(md) + "\n", encoding="utf-8")

    e = html.escape
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>{e(title)}</title><style>body{{font-family:sans-serif;max-width:1200px;"
        "margin:auto}img{margin:4px;border:1px solid #ccc;vertical-align:top}"
        "td,th{padding:2px 8px;text-align:left}pre{background:#f4f4f4;padding:8px}</style>",
        f"</head><body><h1>{e(title)}</h1><p>Goal: <b>{e(goal)}</b></p>",
        f"<pre>{e(json.dumps(facts, indent=1))}</pre><p>{e(LEGEND)}</p><h2>Start</h2>",
    ]
    parts += [f"<img src='{e(img)}'>" for img in start_images]
    for s in play.steps:
        if not s.images:
            continue
        parts.append(
            f"<h2>Step {s.step}: {e(s.action)}</h2><p>At ({s.position[0]:.2f}, "
            f"{s.position[1]:.2f}), heading {s.heading_deg:.0f}°. Waypoint: "
            f"{e(_waypoint(s) or '-')}. {e(s.reason)}</p>"
        )
        parts += [f"<img src='{e(img)}'>" for img in s.images]
    parts.append(
        "<h2>Actions</h2><table><tr><th>step</th><th>action</th><th>position</th>"
        "<th>heading</th><th>waypoint</th><th>reason</th></tr>"
    )
    for s in _rows(play.steps):
        parts.append(
            f"<tr><td>{s.step}</td><td>{e(s.action)}</td><td>({s.position[0]:.2f}, "
            f"{s.position[1]:.2f})</td><td>{s.heading_deg:.0f}</td><td>{e(_waypoint(s))}</td>"
            f"<td>{e(s.reason)}</td></tr>"
        )
    parts.append("</table></body></html>")
    html_path = out_dir / "report.html"
    html_path.write_text("\n".join(parts), encoding="utf-8")
    return md_path, html_path
