"""smolagents 1.26 (`[mcp]`, mcp<2) plays a short ObjectNav episode through glmap-mcp.

Its MCP adapter does not import with mcp 2.x, so it runs in its own venv (.ci/frameworks.sh) as
run_smolagents.py. Its default agent, the CodeAgent, calls the tools as Python functions, so
optional arguments may be left out; the limits measured here are documented in
docs/frameworks/smolagents.md.
"""

from __future__ import annotations

import pytest

from tests.frameworks import episode
from tests.frameworks.venvs import GLMAP_MCP, run_json


@pytest.mark.slow  # starts glmap-mcp
def test_smolagents_code_agent_plays_the_episode_through_tool_collection(tmp_path):
    out = run_json("smolagents", "run_smolagents.py", str(GLMAP_MCP), str(tmp_path))
    assert out["answer"] == "episode over"
    assert set(episode.TOOLS) <= set(out["tools"])
    assert episode.problems([tuple(r) for r in out["replies"]]) == []
    # Its own limits, asserted so a release that lifts them shows up here (then update the docs):
    # every argument is required in the schema its tool-calling models see (mcpadapt drops
    # `required` and marks nothing nullable), and a reply is its first content block only.
    assert "episode" in out["required_sim_reset"] and "session" in out["required_sim_reset"]
    assert out["reply_type"] == "str"


@pytest.mark.slow  # starts glmap-mcp
def test_the_documented_adapter_hands_the_replies_images_to_the_code_agents_model(tmp_path):
    out = run_json("smolagents", "run_smolagents.py", str(GLMAP_MCP), str(tmp_path), "pictures")
    assert out["answer"] == "episode over"
    assert episode.problems([tuple(r) for r in out["replies"]]) == []
    assert sum(out["step_images"]) >= 5 and out["images_seen"] >= 1
    assert out["formats"] == ["JPEG", "PNG"]  # camera views, and the maps (value_map, nav_step)


@pytest.mark.slow  # plays 29 simulator steps
def test_smolagents_code_agent_plays_the_episode_with_the_in_process_tools(tmp_path):
    # The same episode through Toolset.as_smolagents_tools() in this venv (no MCP adapter):
    # smolagents' default agent calls them as Python functions and prints their text.
    pytest.importorskip("smolagents")
    from smolagents import CodeAgent

    from glmap_tools.toolset import Toolset
    from tests.frameworks.smolagents_model import ScriptedModel
    from tests.test_server_fixtures import config

    with Toolset(config(tmp_path)) as tools:
        model = ScriptedModel()
        agent = CodeAgent(tools=tools.as_smolagents_tools(), model=model, max_steps=12)
        answer = agent.run(f"Find the goal of {episode.EPISODE}.")
    assert answer == "episode over"
    assert episode.problems(model.replies) == []
