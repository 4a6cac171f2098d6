"""Play the scripted ObjectNav episode through smolagents 1.26 (runs in .ci/venvs/smolagents).

    python tests/frameworks/run_smolagents.py GLMAP_MCP MAPS_DIR [pictures]

`ToolCollection.from_mcp` (mcpadapt, mcp 1.x) over stdio and smolagents' default agent, the
CodeAgent, whose model writes Python that calls the tools. smolagents has no test model, so
`ScriptedModel` (smolagents_model.py) is a minimal `Model`: each step's code is one call chosen
by tests/frameworks/episode.py from the printed replies. Also records what the adapter gives the
model: whether optional arguments stay optional and what a tool returns (first block only).
Prints one JSON object. `pictures`: the same episode with the adapter and step callback of
docs/frameworks/smolagents.md ("Getting the pictures", taken from the page as written), and how
many images reached the model.
"""

from __future__ import annotations

import json
import re
import sys
import time
from pathlib import Path
from typing import Any

from mcp import StdioServerParameters
from mcpadapt.core import MCPAdapt
from smolagents import CodeAgent, ToolCollection
from smolagents.models import get_tool_json_schema

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from tests.frameworks import episode  # noqa: E402
from tests.frameworks.smolagents_model import ScriptedModel  # noqa: E402


def main(command: str, maps_dir: str) -> dict[str, Any]:
    args = ["--maps-dir", maps_dir, "--embedder", "hashing"]
    server = StdioServerParameters(command=command, args=args)
    start = time.perf_counter()
    with ToolCollection.from_mcp(server, trust_remote_code=True, structured_output=False) as tools:
        model = ScriptedModel()
        agent = CodeAgent(tools=list(tools.tools), model=model, max_steps=12)
        answer = agent.run(f"Find the goal of {episode.EPISODE}.")
        schemas = {t.name: get_tool_json_schema(t)["function"] for t in tools.tools}
        reset = next(t for t in tools.tools if t.name == "sim_reset")
        shown = reset(episode=episode.EPISODE, size="160x120")  # what a direct call returns
    return {
        "answer": answer,
        "replies": model.replies,
        "tools": sorted(schemas),
        # smolagents marks an argument optional only when its input says nullable
        "required_sim_reset": schemas["sim_reset"]["parameters"]["required"],
        "reply_type": type(shown).__name__,
        "seconds": round(time.perf_counter() - start, 1),
    }


def documented_adapter() -> dict[str, Any]:
    """The definitions of docs/frameworks/smolagents.md's pictures block, as written."""
    text = (REPO / "docs" / "frameworks" / "smolagents.md").read_text(encoding="utf-8")
    (block,) = [b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "KeepPictures" in b]
    names: dict[str, Any] = {}
    exec(block.split("\nserver = ")[0], names)  # the imports, the adapter and the callback
    return names


def pictures(command: str, maps_dir: str) -> dict[str, Any]:
    doc = documented_adapter()
    args = ["--maps-dir", maps_dir, "--embedder", "hashing"]
    server = StdioServerParameters(command=command, args=args)
    with MCPAdapt(server, doc["KeepPictures"]()) as tools:
        model = ScriptedModel()
        agent = CodeAgent(
            tools=tools, model=model, max_steps=12, step_callbacks=[doc["show_pictures"]]
        )
        answer = agent.run(f"Find the goal of {episode.EPISODE}.")
    steps = [getattr(s, "observations_images", None) or [] for s in agent.memory.steps]
    return {
        "answer": answer,
        "replies": model.replies,
        "step_images": [len(images) for images in steps],
        "formats": sorted({image.format for images in steps for image in images}),
        "images_seen": model.images_seen,
    }


if __name__ == "__main__":
    if sys.argv[3:4] == ["pictures"]:
        print(json.dumps(pictures(*sys.argv[1:3])))
    else:
        print(json.dumps(main(*sys.argv[1:3])))
