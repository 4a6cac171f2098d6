"""`python -m glmap_tools.bench tokens`: what the server costs a model in bytes (~tokens).

Prints, per tool, the bytes of its tools/list entry (description, input schema, output
schema) and the total against the target (issue 12: tools/list <= 12 KB, MET or MISSED),
then the bytes of typical results (text blocks and structured content apart) on a map of
the small test scene. Bytes are of the compact JSON the SDK sends; a token is ~4 bytes.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any

from glmap_tools import synthetic
from glmap_tools.bench.report import Report
from glmap_tools.map import MapConfig

# Imports inside functions stay there: anyio, cv2, gaussians, mcp load on first use: `bench tokens`
# and `bench startup` stay light.

TOOLS_LIST_TARGET_BYTES = 12 * 1024


def compact(data: Any) -> int:
    """Bytes of `data` as compact JSON (what goes on the wire)."""
    return len(json.dumps(data, separators=(",", ":"), ensure_ascii=False).encode())


def tool_sizes(tools: list[Any]) -> list[tuple[str, int, int, int, int]]:
    """(name, total, description, input schema, output schema) bytes per tool."""
    rows = []
    for tool in tools:
        d = tool.model_dump(mode="json", by_alias=True, exclude_none=True)
        rows.append(
            (
                tool.name,
                compact(d),
                compact(d.get("description", "")),
                compact(d.get("inputSchema", {})),
                compact(d["outputSchema"]) if "outputSchema" in d else 0,
            )
        )
    return rows


def result_sizes(result: Any) -> tuple[int, int, int]:
    """(text bytes, image bytes as base64, structured-content bytes) of one tool result."""
    text = sum(len(c.text.encode()) for c in result.content if c.type == "text")
    images = sum(len(c.data) for c in result.content if c.type == "image")
    structured = compact(result.structured_content) if result.structured_content else 0
    return text, images, structured


async def run(args: argparse.Namespace) -> int:
    from mcp import Client

    from glmap_tools.app.frames import observe_arguments
    from glmap_tools.server import ServerConfig, build_server

    report = Report("bench tokens")
    with tempfile.TemporaryDirectory() as tmp:
        config = ServerConfig(
            maps_dir=Path(tmp),
            embedder="hashing",
            warm_up=False,
            map_config=MapConfig(voxel_size=0.04),
        )
        async with Client(build_server(config), mode="legacy") as client:
            listed = await client.list_tools()
            rows = tool_sizes(listed.tools)
            total = compact(
                {
                    "tools": [
                        t.model_dump(mode="json", by_alias=True, exclude_none=True)
                        for t in listed.tools
                    ]
                }
            )
            print(f"{'tool':<16}{'total':>8}{'descr':>8}{'input':>8}{'output':>8}  (bytes)")
            for name, size, descr, inp, out in sorted(rows, key=lambda r: -r[1]):
                print(f"{name:<16}{size:>8}{descr:>8}{inp:>8}{out:>8}")
            print(
                f"{'(sum)':<16}{sum(r[1] for r in rows):>8}{sum(r[2] for r in rows):>8}"
                f"{sum(r[3] for r in rows):>8}{sum(r[4] for r in rows):>8}"
            )
            report.check(
                f"tools/list, {len(rows)} tools (~{total // 4} tokens)",
                total / 1024,
                "<=",
                TOOLS_LIST_TARGET_BYTES / 1024,
                "KB",
            )
            boxes = (
                synthetic.floor()
                + synthetic.chair(0.0, 0.0, object_id=1)
                + synthetic.table(1.4, 0.3, 2)
                + synthetic.chair(-1.6, 0.4, color=(0.2, 0.3, 0.8), object_id=3)
            )
            frame, ids = synthetic.view(boxes, (0.0, -2.6, 1.4), (0.0, 0.3, 0.4), 160, 120)
            objects = [
                {"id": 1, "label": "chair", "description": "a red wooden chair"},
                {"id": 2, "label": "table", "description": "a brown dining table"},
                {"id": 3, "label": "chair", "description": "a blue office chair"},
            ]
            groups = [{"id": 1, "description": "dining corner", "members": [1, 2]}]
            calls: list[tuple[str, dict[str, Any]]] = [
                ("observe_frame", observe_arguments(frame, ids, objects, groups)),
                ("find_instance", {"query": "a chair", "top_k": 5}),
                ("find_region", {"query": "dining corner"}),
                ("what_is_at", {"x": 0.0, "y": 0.0, "radius": 1.0}),
                ("describe_unit", {"id": 1}),
                ("map_summary", {"include_image": False}),
                ("list_maps", {}),
            ]
            print(f"\n{'result of':<16}{'text':>8}{'struct':>8}  (bytes; images apart)")
            for name, arguments in calls:
                result = await client.call_tool(name, arguments)
                if result.is_error:
                    raise RuntimeError(f"{name} failed: {result.content}")
                text, _, structured = result_sizes(result)
                print(f"{name:<16}{text:>8}{structured:>8}")
    return report.finish()


def main(argv: list[str] | None = None) -> int:
    import anyio

    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench tokens")
    args = parser.parse_args(argv)
    return int(anyio.run(run, args) or 0)
