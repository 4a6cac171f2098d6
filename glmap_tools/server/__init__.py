"""The GLMap MCP server: `build_server(config)` -> tools and glmap:// resources for agents."""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.lazy import lazy_getattr

if TYPE_CHECKING:
    from glmap_tools.server.app import build_server
    from glmap_tools.server.config import ServerConfig

# Loaded on first use: `glmap-mcp` (glmap_tools.server.cli) answers its handshake before
# the MCP SDK and the tools are imported.
_LAZY = {"build_server": "glmap_tools.server.app", "ServerConfig": "glmap_tools.server.config"}
__all__ = ["ServerConfig", "build_server"]
__getattr__ = lazy_getattr(__name__, _LAZY, globals())
