"""The MCP client session every agent plays through, and the agents' image size.

`open_session` gives an in-memory client session on `build_server(config)` by default (no
process, no port), or a session on a stdio server command or a streamable-HTTP URL. The
runner (`agents.runner`, which exports both names too) and the LLM agent
(`agents.llm_agent`) take them from here.
"""

from __future__ import annotations

import shlex
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from glmap_tools.errors import InvalidInputError

# Imports inside functions stay there: mcp (its SDK, anyio, httpx) and glmap_tools.server
# load when a session opens: `glmap` imports eval.spec, and through it agents.runner, to
# build its parser.

AGENT_SIZE = "320x240"


@asynccontextmanager
async def open_session(
    config: Any = None, *, server_command: str | None = None, server_url: str | None = None
) -> AsyncIterator[Any]:
    """An open MCP client session: in memory on `build_server(config)` by default.

    Args:
        config: a `glmap_tools.server.ServerConfig` for the in-memory server.
        server_command: a stdio server command line (e.g. 'glmap-mcp --embedder hashing').
        server_url: a streamable-HTTP URL (e.g. 'http://127.0.0.1:8765/mcp').
    """
    from mcp import Client

    if server_command and server_url:
        raise InvalidInputError("give server_command or server_url, not both.")
    target: Any
    if server_command:
        from mcp.client.stdio import StdioServerParameters

        argv = shlex.split(server_command)
        target = StdioServerParameters(command=argv[0], args=argv[1:])
    elif server_url:
        target = server_url
    else:
        from glmap_tools.server import build_server

        target = build_server(config)
    async with Client(target) as client:
        yield client
