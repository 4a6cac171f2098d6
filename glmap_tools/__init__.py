"""glmap-tools: the Multi-Scale Gaussian-Language Map (GLMap) as a library and MCP server."""

from glmap_tools.errors import GLMapError

__version__ = "0.1.0"
__all__ = ["GLMapError", "__version__"]
