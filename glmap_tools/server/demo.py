"""`glmap demo`: walk a simulated apartment through MCP calls and write a readable transcript.

Builds the server in process, connects a real MCP client session to it, plays one ObjectNav
episode (look around, find the goal in the map, walk to it, stop), queries the map along
the way (find_instance, find_region, what_is_at, describe_unit, render_view, map_summary),
and writes `out/demo/` with every image and `transcript.md` / `transcript.html` of every
call and its result.
"""

from __future__ import annotations

import argparse
import base64
import html
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from glmap_tools.errors import GLMapError

LOOK_AROUND_TURNS = 12  # 12 x 30 degrees
ARRIVE_DISTANCE = 0.9  # m from the goal's centroid
MAX_TEXT = 2500  # characters of a result shown in the transcript
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
    def write(self, title: str, intro: str) -> tuple[Path, Path]:
        """Write transcript.md and transcript.html; return their paths."""
        md = [f"# {title}", "", intro, ""]
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
            f"</head><body><h1>{html.escape(title)}</h1><p>{html.escape(intro)}</p>",
        ]
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


def _status(result: Any) -> dict[str, Any]:
    if result.is_error:
        raise GLMapError(f"the demo's simulator call failed: {result.content[0].text}")
    return dict(json.loads(result.content[0].text))


def _turn_towards(heading_deg: float, x: float, y: float, tx: float, ty: float) -> str | None:
    """'turn_left'/'turn_right' to face (tx, ty) within 15 degrees, or None when facing it."""
    want = math.degrees(math.atan2(ty - y, tx - x))
    diff = (want - heading_deg + 180.0) % 360.0 - 180.0
    if abs(diff) <= 15.0:
        return None
    return "turn_left" if diff > 0 else "turn_right"


async def tour(rec: Recorder, scene: int, seed: int, max_steps: int) -> dict[str, Any]:
    """Play one ObjectNav episode with the map's help; return the final status."""
    await rec.call("list_maps", {}, "What maps are saved already?")
    state = _status(
        await rec.call(
            "sim_reset",
            {"task": "objectnav", "scene": scene, "seed": seed},
            "Start an ObjectNav episode; the first frame goes into a fresh map.",
        )
    )
    goal = state["goal"]
    state = _status(
        await rec.call(
            "sim_step",
            {"action": "turn_left", "repeat": LOOK_AROUND_TURNS},
            "Look around: twelve 30-degree turns, each frame added to the map.",
        )
    )
    hits = await rec.call(
        "find_instance", {"query": goal, "top_k": 3}, f"Ask the map where the {goal} is."
    )
    await rec.call("find_instance", {"query": "something to sit on", "top_k": 3})
    await rec.call("find_region", {"query": "a place to cook", "top_k": 2})
    target: dict[str, Any] | None = None
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
    steps = state["steps"]
    blocked = 0
    while target is not None and state["status"] == "running" and steps < max_steps:
        x, y = state["position"]
        tx, ty = target["centroid"][:2]
        if math.hypot(tx - x, ty - y) <= ARRIVE_DISTANCE:
            break
        turn = _turn_towards(state["heading_deg"], x, y, tx, ty)
        if blocked:
            action, repeat, blocked = "turn_right", 3, 0
        elif turn:
            action, repeat = turn, 1
        else:
            action, repeat = "move_forward", 2
        state = _status(
            await rec.call("sim_step", {"action": action, "repeat": repeat}, f"towards {goal}")
        )
        blocked = 1 if state["collided"] else 0
        steps = state["steps"]
        if blocked and state["status"] == "running":
            state = _status(
                await rec.call("sim_step", {"action": "move_forward", "repeat": 1}, "sidestep")
            )
    x, y = state["position"]
    await rec.call(
        "render_view",
        {"target": "situated", "x": x, "y": y, "heading_deg": state["heading_deg"]},
        "Front, left, back and right views from where the agent stands.",
    )
    await rec.call("render_view", {"target": "map"}, "The whole map from above at an angle.")
    await rec.call("map_summary", {}, "Counts, bounds and the top-down map.")
    await rec.call("save_map", {"name": "demo", "overwrite": True}, "Keep the map.")
    await rec.call(
        "export_ply",
        {"name": "demo", "overwrite": True},
        "Write its Gaussians as a 3DGS PLY file (maps/demo.ply) for a splat viewer.",
    )
    if state["status"] == "running":
        state = _status(await rec.call("sim_step", {"action": "stop"}, "Stop here."))
    return state


async def run(out: Path, scene: int, seed: int, embedder: str, max_steps: int) -> int:
    """Build the server in process, play the tour, write the transcript."""
    from mcp import Client

    from glmap_tools.server import ServerConfig, build_server

    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    out.mkdir(parents=True, exist_ok=True)
    config = ServerConfig(maps_dir=out / "maps", embedder=embedder)  # type: ignore[arg-type]
    start = time.perf_counter()
    async with Client(build_server(config)) as client:
        rec = Recorder(client, out)
        tools = sorted(t.name for t in (await client.list_tools()).tools)
        final = await tour(rec, scene, seed, max_steps)
    outcome = (
        f"Episode result: {final['status']} (goal: {final['goal']}, SPL {final.get('spl', 0)}, "
        f"{final['steps']} steps). "
    )
    intro = (
        f"glmap demo: scene {scene}, episode seed {seed}, embedder {embedder}. The server "
        f"offers {', '.join(tools)}. Each section is one MCP tools/call through a real client "
        f"session, with its arguments, progress notifications, result and images. {outcome}"
        f"Total {time.perf_counter() - start:.1f} s."
    )
    md, page = rec.write("GLMap MCP demo", intro)
    print(f"{outcome}\nwrote {md} and {page} ({len(rec.entries)} calls)")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo",
        help="walk a simulated apartment through the MCP server and write out/demo/",
        description=(
            "Start the GLMap MCP server in process, play one ObjectNav episode through MCP "
            "calls (sim_step, find_instance, find_region, what_is_at, render_view, ...), and "
            "write the images and a transcript (Markdown and HTML) of every call."
        ),
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    p.add_argument("--scene", type=int, default=0, help="generated apartment seed")
    p.add_argument("--seed", type=int, default=1, help="episode seed")
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--max-steps", type=int, default=80, help="actions before giving up")
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
