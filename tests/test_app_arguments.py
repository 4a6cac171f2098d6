"""The app's argument models (glmap_tools.app.arguments, used by the in-process Toolset)
are the ones the MCP SDK builds for the same tools: same schemas, same validation."""

from __future__ import annotations

import pytest
from mcp.server.mcpserver.tools import Tool as ToolInfo
from pydantic import ValidationError

from glmap_tools.app.arguments import argument_model, input_schema, validate_arguments
from glmap_tools.app.catalog import TOOLS
from glmap_tools.server.build import mcp_tool

SDK = {spec.name: ToolInfo.from_function(mcp_tool(spec), name=spec.name) for spec in TOOLS}
BY_NAME = {spec.name: spec for spec in TOOLS}


@pytest.mark.parametrize("name", [spec.name for spec in TOOLS])
def test_every_tool_has_the_input_schema_the_sdk_builds_from_its_signature(name):
    assert input_schema(BY_NAME[name].fn) == SDK[name].parameters
    assert "call" not in argument_model(BY_NAME[name].fn).model_fields


CASES = [
    ("find_instance", {"query": "a chair", "top_k": "3"}),
    ("find_instance", {"query": "a chair", "top_k": 0}),
    ("find_instance", {"top_k": 2}),
    ("what_is_at", {"x": "1.5", "y": -2, "radius": 0.3}),
    ("render_view", {"target": "pose", "pose": '{"matrix": [[1, 0, 0, 0]]}'}),
    ("label_segments", {"frame": "f1", "labels": '[{"id": 1, "label": "chair"}]'}),
    ("label_segments", {"frame": "f1", "labels": "not json"}),
    ("sim_step", {"action": "jump"}),
    ("new_map", {"name": None, "unknown": 1}),
]


@pytest.mark.parametrize(("name", "arguments"), CASES)
def test_arguments_validate_as_the_sdk_validates_them(name, arguments):
    try:
        ours: object = validate_arguments(BY_NAME[name].fn, arguments)
    except ValidationError as exc:
        ours = [(e["loc"], e["type"]) for e in exc.errors()]
    try:
        theirs: object = SDK[name].fn_metadata.validate_arguments(arguments)
    except ValidationError as exc:
        theirs = [(e["loc"], e["type"]) for e in exc.errors()]
    assert ours == theirs
