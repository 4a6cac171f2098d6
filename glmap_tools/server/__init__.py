"""The GLMap MCP server: `build_server(config)` -> tools and glmap:// resources for agents."""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.lazy import lazy_getattr

if TYPE_CHECKING:
    from glmap_tools.app.config import ServerConfig
    from glmap_tools.server.build import build_server

# Loaded on first use: `glmap-mcp` (glmap_tools.server.cli) answers its handshake before
# the MCP SDK and the tools are imported.
_LAZY = {"build_server": "glmap_tools.server.build", "ServerConfig": "glmap_tools.app.config"}
__all__ = ["ServerConfig", "build_server"]
__getattr__ = lazy_getattr(__name__, _LAZY, globals())
