"""The GLMap tools as plain Python functions: one tool set, two faces.

The tools exist once (`catalog.TOOLS`: async functions over a map session, typed with
`Annotated` parameters and pydantic results). `glmap_tools.server.build_server` registers
exactly these on the MCP server; `Toolset` offers them in this process, for frameworks that
take Python functions (ollama, pydantic-ai, LangChain, smolagents):

    from glmap_tools.toolset import Toolset

    with Toolset() as tools:
        tools.call("sim_reset", {"scene": 0})
        print(as_text(tools.call("find_instance", {"query": "a bed"})))

See docs/toolset.md.
"""

from glmap_tools.app.catalog import TOOL_NAMES, TOOLS
from glmap_tools.app.results import ImageResult, Picture, as_text, pictures_of
from glmap_tools.toolset.local import Toolset

__all__ = ["TOOLS", "TOOL_NAMES", "ImageResult", "Picture", "Toolset", "as_text", "pictures_of"]
