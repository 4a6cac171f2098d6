"""pydantic-ai at its default MCP settings plays a short ObjectNav episode through glmap-mcp.

`MCPToolset` over stdio with nothing changed: it gives the server 5 s for the handshake
(issue 13 item 2). The model is pydantic-ai's FunctionModel, scripted by episode.py
(pydantic_ai_model.py; pydantic-ai is imported inside the tests, not when they are collected).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from tests.frameworks import episode

GLMAP_MCP = Path(sys.executable).parent / "glmap-mcp"


@pytest.mark.slow  # starts glmap-mcp, which loads MiniLM in the background
def test_pydantic_ai_default_mcp_toolset_plays_an_objectnav_episode(tmp_path):
    from fastmcp.client.transports import StdioTransport
    from pydantic_ai import Agent
    from pydantic_ai.mcp import MCPToolset
    from pydantic_ai.models.function import FunctionModel

    from tests.frameworks.pydantic_ai_model import ScriptedModel

    model = ScriptedModel()
    server = StdioTransport(command=str(GLMAP_MCP), args=["--maps-dir", str(tmp_path)])
    agent = Agent(FunctionModel(model), toolsets=[MCPToolset(server)])  # default timeouts
    result = agent.run_sync(f"Find the {episode.EPISODE} goal.")
    assert result.output == "episode over"
    assert set(episode.TOOLS) <= set(model.tools)
    assert episode.problems(model.replies) == []
    assert model.images["sim_reset"] >= 1  # the agent's view reaches the model as an image
    assert model.images["value_map"] >= 1


@pytest.mark.slow  # starts glmap-mcp twice
def test_pydantic_ai_needs_max_retries_to_survive_two_bad_calls_in_a_row(tmp_path):
    from fastmcp.client.transports import StdioTransport
    from pydantic_ai import Agent
    from pydantic_ai.exceptions import UnexpectedModelBehavior
    from pydantic_ai.mcp import MCPToolset

    from tests.frameworks.pydantic_ai_model import stumbling_model

    def server() -> StdioTransport:
        args = ["--maps-dir", str(tmp_path), "--embedder", "hashing"]
        return StdioTransport(command=str(GLMAP_MCP), args=args)

    default = Agent(stumbling_model(2), toolsets=[MCPToolset(server())])
    with pytest.raises(UnexpectedModelBehavior, match="max retries"):
        default.run_sync("Stop at once.")
    patient = Agent(stumbling_model(2), toolsets=[MCPToolset(server(), max_retries=3)])
    assert patient.run_sync("Stop at once.").output == "episode over"
