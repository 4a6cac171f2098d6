"""Every GLMap tool, once: the list both faces (MCP server, in-process Toolset) are built from."""

from __future__ import annotations

from glmap_tools.app import (
    tools_export,
    tools_map,
    tools_nav,
    tools_perception,
    tools_sim,
    tools_sqa,
    tools_store,
    tools_view,
)
from glmap_tools.app.runtime import ToolSpec

TOOLS: tuple[ToolSpec, ...] = (
    *tools_map.TOOLS,
    *tools_perception.TOOLS,
    *tools_store.TOOLS,
    *tools_view.TOOLS,
    *tools_export.TOOLS,
    *tools_sim.TOOLS,
    *tools_nav.TOOLS,
    *tools_sqa.TOOLS,
)
TOOL_NAMES = tuple(t.name for t in TOOLS)
