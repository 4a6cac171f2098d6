"""The text blocks a client reads from the simulator, navigation and situated-QA tools, and
the script that writes their golden file (tests/data/tool_texts.json).

The calls run one in-memory server (hashing embedder, 160x120 frames) through a fixed
sequence: an empty map, two observed frames, a situated question, then episodes that run,
walk, get blocked, end in success and run out of steps. The agents parse these texts as
JSON, so a change to any of them is a change clients see:

    python -m tests.tool_texts          # rewrite the golden file; say why in the commit
"""

from __future__ import annotations

import asyncio
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from mcp import Client

from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

GOLDEN = Path(__file__).parent / "data" / "tool_texts.json"
EPISODE = "tune/objectnav/s03-013"
FRAME_FILES = ("rgb", "depth")  # left out of the recorded arguments (base64 images)

CALLS: list[tuple[str, dict[str, Any]]] = [
    ("value_map", {}),
    ("map_summary", {"include_image": False}),
    ("observe_frame", frame_args((0.0, -2.6, 1.4))),
    ("observe_frame", frame_args((-2.5, 1.5, 1.4))),
    ("map_summary", {}),
    (
        "locate_situation",
        {
            "situation": "I am standing next to the dining table, facing the blue chair",
            "question": "what is on my left?",
            "topdown": True,
        },
    ),
    ("sim_reset", {"episode": EPISODE}),
    ("sim_step", {"action": "turn_left", "repeat": 2}),
    ("look_around", {}),
    ("find_instance", {"query": "a bed"}),
    ("value_map", {}),
    ("value_map", {"units": "instances", "scores": {"1": 0.5}, "priors": {"bedroom": 0.8}}),
    ("frontiers", {"top_k": 3}),
    ("navigate_to", {"x": 15.43, "y": 3.93, "max_steps": 4}),
    ("navigate_to", {"x": 9.12, "y": 4.58}),
    ("value_map", {"scores": {"1": 0.9, "2": 0.1}}),
    ("nav_step", {"actions": 3}),
    ("nav_step", {"actions": 2, "details": True, "images": True}),
    ("navigate_to", {"x": 0.0, "y": 0.0}),
    ("navigate_to", {"unit_id": 1}),
    ("nav_step", {"actions": 150}),
    ("value_map", {"clear": True}),
    ("sim_step", {"action": "stop"}),
    ("sim_reset", {"task": "instnav", "scene": 2, "seed": 3}),
    ("nav_step", {"actions": 5, "policy": "frontier"}),
    ("sim_reset", {"episode": "bench/objectnav/s00-000", "max_steps": 12}),
    ("nav_step", {"actions": 20, "details": True}),
    ("sim_reset", {"episode": "bench/instnav/s01-000", "keep_map": True}),
    ("nav_step", {"actions": 40, "execute_stop": True}),
    ("navigate_to", {"unit_id": 2, "max_steps": 30}),
    ("sim_step", {"action": "stop"}),
]


async def record() -> list[dict[str, Any]]:
    """Each call's name, arguments (frame files left out), whether it failed, its text
    blocks, the MIME types of its images, and whether it sent structured content."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        server = build_server(config(Path(tmp), sim_size=(160, 120)))
        async with Client(server) as client:
            for name, args in CALLS:
                result = await client.call_tool(name, args)
                rows.append(
                    {
                        "call": name,
                        "args": {k: v for k, v in args.items() if k not in FRAME_FILES},
                        "error": result.is_error,
                        "texts": [c.text for c in result.content if c.type == "text"],
                        "images": [c.mime_type for c in result.content if c.type == "image"],
                        "structured": result.structured_content is not None,
                    }
                )
    return rows


def main() -> int:
    rows = asyncio.run(record())
    GOLDEN.write_text(json.dumps(rows, indent=1, ensure_ascii=False) + "\n")
    print(f"wrote {GOLDEN} ({len(rows)} calls)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
