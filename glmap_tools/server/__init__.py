"""The GLMap MCP server: `build_server(config)` -> tools and glmap:// resources for agents.

The MCP face of glmap_tools.app: `add_tools(server, specs)` registers tool specs (e.g. a
`Toolset`'s `specs`) on any MCPServer.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.lazy import lazy_getattr

if TYPE_CHECKING:
    from glmap_tools.app.config import ServerConfig
    from glmap_tools.server.build import add_tools, build_server

# Loaded on first use: `glmap-mcp` (glmap_tools.server.cli) answers its handshake before
# the MCP SDK and the tools are imported.
_LAZY = {
    "add_tools": "glmap_tools.server.build",
    "build_server": "glmap_tools.server.build",
    "ServerConfig": "glmap_tools.app.config",
}
__all__ = ["ServerConfig", "add_tools", "build_server"]
__getattr__ = lazy_getattr(__name__, _LAZY, globals())
