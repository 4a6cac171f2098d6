"""The GLMap MCP server: `build_server(config)` -> tools and glmap:// resources for agents."""

from glmap_tools.server.app import build_server
from glmap_tools.server.config import ServerConfig

__all__ = ["ServerConfig", "build_server"]
