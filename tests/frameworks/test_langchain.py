"""langchain-mcp-adapters 0.3.2 plays a short ObjectNav episode through glmap-mcp, both ways.

It pins mcp 1.x, so it runs in its own venv (.ci/frameworks.sh) as run_langchain.py, talking
to this venv's glmap-mcp over stdio.
"""

from __future__ import annotations

import os
import signal

import pytest

from glmap_tools.server.linger import lingering_servers
from tests.frameworks import episode
from tests.frameworks.venvs import GLMAP_MCP, run_json


def played(mode: str, maps_dir: str) -> dict:  # type: ignore[type-arg]
    out = run_json("langchain", "run_langchain.py", mode, str(GLMAP_MCP), maps_dir)
    assert out["answer"] == "episode over"
    assert set(episode.TOOLS) <= set(out["tools"])
    assert "episode" in out["tools"]["sim_reset"]  # optional arguments survive the schema
    assert out["images"]["sim_reset"] >= 1  # the agent's view arrives as an image block
    return out


@pytest.mark.slow  # a fresh glmap-mcp for each of the seven calls, relaying to one server
def test_langchain_default_get_tools_keeps_the_episode_with_map_and_linger(tmp_path):
    try:
        out = played("per-call", str(tmp_path))
    finally:
        servers = lingering_servers(str(tmp_path))
        for pid in servers:
            os.kill(pid, signal.SIGTERM)
    assert episode.problems([tuple(r) for r in out["replies"]]) == []
    assert (tmp_path / "langchain-test.glmap").exists()
    assert len(servers) == 1  # the seven calls' processes relayed to one


@pytest.mark.slow  # a fresh glmap-mcp for each of the two calls
def test_langchain_get_tools_without_the_map_option_says_how_to_keep_the_episode(tmp_path):
    out = run_json("langchain", "run_langchain.py", "no-map", str(GLMAP_MCP), str(tmp_path))
    (error,) = out["reply"]  # the adapters hand the model the error text as the reply
    assert error.startswith("Error executing tool sim_step: no simulator episode in this session")
    assert "--map NAME" in error and "client.session(...)" in error


@pytest.mark.slow  # starts glmap-mcp
def test_langchain_explicit_session_plays_the_episode_on_one_server(tmp_path):
    out = played("session", str(tmp_path))
    assert episode.problems([tuple(r) for r in out["replies"]]) == []


@pytest.mark.slow  # plays 29 simulator steps
def test_langchain_loop_plays_the_episode_with_the_in_process_tools(tmp_path):
    # The same loop and episode with Toolset.as_langchain_tools() in this venv (no adapter).
    pytest.importorskip("langchain_core")
    import asyncio

    from glmap_tools.toolset import Toolset
    from tests.frameworks.langchain_loop import play
    from tests.test_server_fixtures import config

    with Toolset(config(tmp_path)) as tools:
        out = asyncio.run(play(tools.as_langchain_tools()))
    assert out["answer"] == "episode over"
    assert "episode" in out["tools"]["sim_reset"]
    assert episode.problems([tuple(r) for r in out["replies"]]) == []
