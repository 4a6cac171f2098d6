"""The GLMap application: sessions, maps, the simulator and the tools, with no transport.

`glmap_tools.server` (MCP) and `glmap_tools.toolset` (in process) are its two faces; see
design.md here.
"""
