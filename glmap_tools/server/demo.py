"""`glmap demo`: the GLMap agent plays an ObjectNav episode through MCP calls; a transcript.

Builds the server in process and connects a real MCP client session to it. The GLMap agent
(`agents.runner`, policy 'glmap': the value map of paper Eq. 7 over instance and region
units, frontiers, the waypoint rule and the FMM planner, run server-side by `nav_step`)
plays one ObjectNav episode at 320x240 and writes `out/demo/episode/` (trace.jsonl of every
call, report.md/html with the egocentric frames and the value maps step by step). Then the
map it built is queried (find_instance, find_region, what_is_at, describe_unit, value_map,
render_view, map_summary), saved and exported as a PLY, and `out/demo/transcript.md` /
`transcript.html` show every call, its result and images.
"""

from __future__ import annotations

import argparse
import base64
import html
import json
import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agents.runner import play_episode

# Imports inside functions stay there: anyio, cv2, gaussians, mcp load on first use: `glmap` imports
# every command module to build its parser.

MAX_TEXT = 2500  # characters of a result shown in the transcript
MAX_EPISODE_MAPS = 6  # value maps of the episode shown in the transcript
IMAGE_EVERY = 4  # the agent fetches the view and the value map every this many calls
ELIDE = 64  # characters of a base64 argument shown


@dataclass
class Entry:
    """One recorded MCP call."""

    index: int
    tool: str
    arguments: dict[str, Any]
    note: str
    texts: list[str]
    images: list[str]
    is_error: bool
    seconds: float
    progress: list[str] = field(default_factory=list)


def _elide(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _elide(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_elide(v) for v in value]
    if isinstance(value, str) and len(value) > 4 * ELIDE:
        return f"{value[:ELIDE]}... ({len(value)} characters)"
    return value


LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
CODE = re.compile(r"`([^`]+)`")


def inline_html(line: str) -> str:
    """One line of Markdown as HTML: escaped, with its links and `code` spans rendered."""
    out = html.escape(line, quote=False)
    out = LINK.sub(lambda m: f"<a href='{html.escape(m.group(2))}'>{m.group(1)}</a>", out)
    return CODE.sub(r"<code>\1</code>", out)


class Recorder:
    """Calls tools through a client session and records each call, its result and images."""

    def __init__(self, client: Any, out: Path, echo: bool = True) -> None:
        self.client = client
        self.out = out
        self.images_dir = out / "images"
        self.images_dir.mkdir(parents=True, exist_ok=True)
        self.entries: list[Entry] = []
        self.echo = echo

    async def call(self, tool: str, arguments: dict[str, Any], note: str = "") -> Any:
        progress: list[str] = []

        async def on_progress(done: float, total: float | None, message: str | None) -> None:
            progress.append(f"{done:g}/{total:g} {message or ''}".strip() if total else f"{done:g}")

        start = time.perf_counter()
        result = await self.client.call_tool(tool, arguments, progress_callback=on_progress)
        seconds = time.perf_counter() - start
        index = len(self.entries) + 1
        texts, images = [], []
        for k, block in enumerate(result.content):
            if block.type == "text":
                texts.append(block.text)
            elif block.type == "image":
                ext = "jpg" if block.mime_type == "image/jpeg" else "png"
                name = f"{index:03d}_{tool}_{k}.{ext}"
                (self.images_dir / name).write_bytes(base64.b64decode(block.data))
                images.append(f"images/{name}")
        entry = Entry(
            index, tool, _elide(arguments), note, texts, images, result.is_error, seconds, progress
        )
        self.entries.append(entry)
        if self.echo:
            flag = "error" if result.is_error else "ok"
            print(f"[{index:02d}] {tool} ({flag}, {seconds * 1000:.0f} ms) {note}", flush=True)
        return result

    # ------------------------------------------------------------------ output
    def write(self, title: str, intro: str, extra: list[str] | None = None) -> tuple[Path, Path]:
        """Write transcript.md and transcript.html; return their paths.

        Args:
            title: page title.
            intro: the first paragraph.
            extra: Markdown lines placed after the intro (the HTML shows their images).
        """
        md = [f"# {title}", "", intro, ""] + list(extra or [])
        for e in self.entries:
            status = "**error**" if e.is_error else "ok"
            md += [f"## {e.index}. `{e.tool}` — {status}, {e.seconds * 1000:.0f} ms", ""]
            if e.note:
                md += [f"*{e.note}*", ""]
            md += ["Arguments:", "", "```json", json.dumps(e.arguments, indent=2), "```", ""]
            if e.progress:
                md += ["Progress: " + " → ".join(e.progress), ""]
            for text in e.texts:
                shown = text if len(text) <= MAX_TEXT else text[:MAX_TEXT] + "\n... (cut)"
                md += ["```", shown, "```", ""]
            md += [f"![{e.tool} image {i + 1}]({img})" for i, img in enumerate(e.images)]
            md.append("")
        md_path = self.out / "transcript.md"
        md_path.write_text("\n".join(md), encoding="utf-8")
        parts = [
            "<!doctype html><html><head><meta charset='utf-8'>",
            f"<title>{html.escape(title)}</title><style>body{{font-family:sans-serif;"
            "max-width:1100px;margin:auto}pre{background:#f4f4f4;padding:8px;overflow:auto;"
            "max-height:420px}img{margin:4px;border:1px solid #ccc}.err{color:#b00}</style>",
            f"</head><body><h1>{html.escape(title)}</h1><p>{inline_html(intro)}</p>",
        ]
        for line in extra or []:
            if line.startswith("!["):
                parts.append(f"<img src='{html.escape(line.split('](')[1][:-1])}'>")
            elif line.startswith("## "):
                parts.append(f"<h2>{html.escape(line[3:])}</h2>")
            elif line:
                parts.append(f"<p>{inline_html(line)}</p>")
        for e in self.entries:
            cls = " class='err'" if e.is_error else ""
            parts.append(
                f"<h2{cls}>{e.index}. {html.escape(e.tool)} "
                f"({'error' if e.is_error else 'ok'}, {e.seconds * 1000:.0f} ms)</h2>"
            )
            if e.note:
                parts.append(f"<p><i>{html.escape(e.note)}</i></p>")
            parts.append(f"<pre>{html.escape(json.dumps(e.arguments, indent=2))}</pre>")
            if e.progress:
                parts.append(f"<p>Progress: {html.escape(' → '.join(e.progress))}</p>")
            for text in e.texts:
                shown = text if len(text) <= MAX_TEXT else text[:MAX_TEXT] + "\n... (cut)"
                parts.append(f"<pre>{html.escape(shown)}</pre>")
            parts.extend(f"<img src='{img}'>" for img in e.images)
        parts.append("</body></html>")
        html_path = self.out / "transcript.html"
        html_path.write_text("\n".join(parts), encoding="utf-8")
        return md_path, html_path


async def queries(rec: Recorder, play: dict[str, Any], goal: str) -> None:
    """Ask the map the agent built about the goal and its surroundings; save and export it."""
    hits = await rec.call(
        "find_instance", {"query": goal, "top_k": 3}, f"Where is the {goal} in the map?"
    )
    await rec.call("find_region", {"query": "a place to cook", "top_k": 2})
    await rec.call(
        "value_map", {"goal": goal}, "The value map (Eq. 7) the agent navigated by, at the end."
    )
    found = hits.structured_content["hits"] if not hits.is_error else []
    if found:
        target = found[0]
        tx, ty = target["centroid"][:2]
        await rec.call("describe_unit", {"id": target["id"]}, "Everything about the best hit.")
        await rec.call("what_is_at", {"x": tx, "y": ty, "radius": 0.5}, "What else is around it?")
        await rec.call(
            "render_view",
            {"target": "instance", "unit_id": target["id"]},
            "Look at the hit in the map's Gaussians.",
        )
    x, y = play["position"]
    await rec.call(
        "render_view",
        {"target": "situated", "x": x, "y": y, "heading_deg": play["heading_deg"]},
        "Front, left, back and right views from where the agent stopped.",
    )
    await rec.call("render_view", {"target": "map"}, "The whole map from above at an angle.")
    await rec.call("map_summary", {}, "Counts, bounds and the top-down map.")
    await rec.call("save_map", {"name": "demo", "overwrite": True}, "Keep the map.")
    await rec.call(
        "export_ply",
        {"name": "demo", "overwrite": True},
        "Write its Gaussians as a 3DGS PLY file (maps/demo.ply) for a splat viewer.",
    )


def episode_section(result: dict[str, Any], images: list[str], calls: int) -> list[str]:
    """Markdown of the agent's episode: its result and its value maps, linked from episode/."""
    maps = [i for i in images if i.endswith(".png")][-MAX_EPISODE_MAPS:]
    facts = ", ".join(f"{k} {result[k]}" for k in ("success", "spl", "steps", "collisions"))
    lines = [
        "## The episode, played by the GLMap agent",
        "",
        f"{calls} MCP calls (sim_reset, then one nav_step per action): {facts}. Full report "
        "with every fetched egocentric frame and value map: "
        "[episode/report.html](episode/report.html) ([Markdown](episode/report.md)); every "
        "call: `episode/trace.jsonl`.",
        "",
        "Value maps (heat = Eq. 7 over instance and region units; cyan = frontiers; magenta "
        "= waypoint; green = planned path; blue = camera trajectory; red = the agent):",
        "",
    ]
    lines += [f"![value map]({m})" for m in maps]
    return lines + [""]


async def run(out: Path, scene: int, seed: int, embedder: str, max_steps: int) -> int:
    """Build the server in process, let the GLMap agent play, query the map, write it all."""
    from mcp import Client

    from glmap_tools.server import ServerConfig, build_server

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    out.mkdir(parents=True, exist_ok=True)
    config = ServerConfig(maps_dir=out / "maps", embedder=embedder)  # type: ignore[arg-type]
    start = time.perf_counter()
    async with Client(build_server(config)) as client:
        rec = Recorder(client, out)
        tools = sorted(t.name for t in (await client.list_tools()).tools)
        await rec.call("list_maps", {}, "What maps are saved already?")
        print("the GLMap agent plays the episode (one nav_step per action) ...", flush=True)
        result, traced = await play_episode(
            client,
            {"task": "objectnav", "scene": scene, "max_steps": max_steps},
            "glmap",
            seed=seed,
            out_dir=out / "episode",
            image_every=IMAGE_EVERY,
            title=f"GLMap agent, scene {scene}, seed {seed}",
        )
        final = traced.records[-1].data()
        await queries(rec, final, str(final["goal"]))
    images = [f"episode/{i}" for r in traced.records for i in r.images]
    outcome = (
        f"Episode result: {final['status']} (goal: {final['goal']}, SPL {final.get('spl', 0)}, "
        f"{final['steps']} steps, {len(traced.records)} calls). "
    )
    intro = (
        f"glmap demo: scene {scene}, episode seed {seed}, embedder {embedder}. The server "
        f"offers {', '.join(tools)}. Each section below is one MCP tools/call through a real "
        f"client session, with its arguments, progress notifications, result and images. "
        f"{outcome}Total {time.perf_counter() - start:.1f} s."
    )
    md, page = rec.write(
        "GLMap MCP demo", intro, episode_section(result, images, len(traced.records))
    )
    print(f"{outcome}\nwrote {md}, {page} and {out / 'episode' / 'report.html'}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo",
        help="the GLMap agent plays an ObjectNav episode through the MCP server -> out/demo/",
        description=(
            "Start the GLMap MCP server in process; the GLMap agent plays one ObjectNav "
            "episode through MCP calls (nav_step: value map, frontiers, waypoint, FMM plan) "
            "and writes its trace and report (frames and value maps) to out/demo/episode/; "
            "then the map is queried (find_instance, value_map, render_view, ...), saved and "
            "exported, with a transcript (Markdown and HTML) of every call."
        ),
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    p.add_argument("--scene", type=int, default=0, help="generated apartment seed")
    p.add_argument("--seed", type=int, default=1, help="episode seed")
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--max-steps", type=int, default=120, help="episode step limit")
    p.set_defaults(func=run_demo)


def run_demo(args: argparse.Namespace) -> int:
    import anyio

    return int(anyio.run(run, args.out, args.scene, args.seed, args.embedder, args.max_steps) or 0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="glmap")
    register(parser.add_subparsers(dest="command"))
    rest = sys.argv[1:] if argv is None else argv
    return run_demo(parser.parse_args(["demo", *rest]))


if __name__ == "__main__":
    raise SystemExit(main())
