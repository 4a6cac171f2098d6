"""Play the scripted ObjectNav episode through langchain-mcp-adapters (runs in .ci/venvs/langchain).

    python tests/frameworks/run_langchain.py per-call|session|no-map GLMAP_MCP MAPS_DIR

per-call: the default `MultiServerMCPClient(...).get_tools()`, which starts a fresh server for
every tool call; it is launched with `--map --linger` so those processes relay to one
background server that keeps the map and episode. session: one server for the whole episode
through `client.session(...)` and `load_mcp_tools`. no-map: `get_tools()` on a server launched
without `--map`: `sim_reset`, then the `sim_step` that finds no episode in its new process;
prints its reply (the error).
The loop and its model (langchain-core's GenericFakeChatModel, whose
messages come from tests/frameworks/episode.py) are in langchain_loop.py. Prints one JSON
object: the replies, how many image blocks each tool's reply carried, the tool names and
the seconds taken.
"""

from __future__ import annotations

import asyncio
import json
import sys
import time
from pathlib import Path
from typing import Any

from langchain_mcp_adapters.client import MultiServerMCPClient
from langchain_mcp_adapters.tools import load_mcp_tools

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.frameworks.langchain_loop import play  # noqa: E402


async def main(mode: str, command: str, maps_dir: str) -> dict[str, Any]:
    args = ["--maps-dir", maps_dir, "--embedder", "hashing"]
    if mode == "per-call":
        args += ["--map", "langchain-test", "--linger", "20"]
    client = MultiServerMCPClient(
        {"glmap": {"transport": "stdio", "command": command, "args": args}}
    )
    start = time.perf_counter()
    if mode == "per-call":
        out = await play(await client.get_tools())
    elif mode == "no-map":
        tools = {t.name: t for t in await client.get_tools()}
        await tools["sim_reset"].ainvoke({"episode": "tune/objectnav/s03-013", "size": "160x120"})
        reply = await tools["sim_step"].ainvoke({"action": "turn_left"})
        return {"reply": [block.get("text", block.get("type")) for block in reply]}
    elif mode == "session":
        async with client.session("glmap") as session:
            out = await play(await load_mcp_tools(session))
    else:
        raise SystemExit(f"mode {mode!r}: use per-call, session or no-map")
    return {**out, "seconds": round(time.perf_counter() - start, 1)}


if __name__ == "__main__":
    print(json.dumps(asyncio.run(main(*sys.argv[1:4]))))
