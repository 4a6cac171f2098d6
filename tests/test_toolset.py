"""The in-process face (glmap_tools.toolset) is the MCP server's tool set: same names,
descriptions, schemas, validation and answers; and frameworks can take its functions."""

from __future__ import annotations

import inspect
import json

import pytest
from mcp import Client

from glmap_tools.errors import InvalidInputError
from glmap_tools.server import build_server
from glmap_tools.toolset import TOOL_NAMES, ImageResult, Toolset, as_text
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
def toolset(tmp_path):
    with Toolset(config(tmp_path)) as tools:
        yield tools


def _listing(tools) -> list[dict]:
    return [t.model_dump(mode="json", by_alias=True, exclude_none=True) for t in tools]


async def test_both_faces_list_the_same_tools_descriptions_and_schemas(tmp_path, toolset):
    async with Client(build_server(config(tmp_path))) as client:
        served = _listing((await client.list_tools()).tools)
    local = _listing(toolset.tool_list())
    assert [t["name"] for t in served] == list(TOOL_NAMES) == [t["name"] for t in local]
    assert served == local
    assert len(served) == 21


def test_the_functions_have_the_tools_names_docstrings_and_signatures_without_call(toolset):
    for fn in toolset.functions():
        params = inspect.signature(fn).parameters
        assert "call" not in params and "ctx" not in params
        schema = toolset.input_schema(fn.__name__)
        assert list(params) == list(schema["properties"])
        doc = inspect.getdoc(fn)
        head = toolset.description(fn.__name__)
        assert doc == head if not params else doc.startswith(head + "\n\nArgs:\n")
        for arg in params:  # every argument is described (smolagents and ollama need it)
            assert f"\n    {arg}: " in doc


def test_ollama_converts_every_function_keeping_names_arguments_and_descriptions(toolset):
    from ollama._utils import convert_function_to_tool

    for fn in toolset.functions():
        tool = convert_function_to_tool(fn).function
        assert tool.name == fn.__name__
        assert " ".join(tool.description.split()) == " ".join(
            toolset.description(fn.__name__).split()
        )
        props = tool.parameters.properties
        assert list(props) == list(inspect.signature(fn).parameters)
        assert all(p.description for p in props.values()), fn.__name__
    find = next(f for f in toolset.functions() if f.__name__ == "find_instance")
    props = convert_function_to_tool(find).function.parameters.properties
    assert props["query"].description == "what to look for, in words"
    assert props["top_k"].type == "integer" and "(default 5)" in props["top_k"].description


def test_ollama_keeps_the_flattened_schemas_whole_and_flattened_calls_work(toolset):
    from ollama._types import Tool

    for tool in toolset.ollama_tools():
        kept = Tool.model_validate(tool).model_dump(exclude_none=True, by_alias=True)
        assert json.loads(json.dumps(kept)) == json.loads(json.dumps(tool))  # nothing dropped
    by_name = {t["function"]["name"]: t["function"]["parameters"] for t in toolset.ollama_tools()}
    nav = by_name["nav_step"]["properties"]
    assert (
        "1..200" in nav["actions"]["description"] and "default 1" in nav["actions"]["description"]
    )
    frame = by_name["observe_frame"]
    assert {"rgb__base64", "rgb__path", "pose__matrix", "annotations__objects"} <= set(
        frame["properties"]
    )
    assert (
        frame["properties"]["annotations__objects"]["items"]["properties"]["id"]["maximum"] == 65535
    )

    flat: dict = {}
    for key, value in frame_args().items():  # what a model reading the flat schema sends
        if isinstance(value, dict):
            for k, v in value.items():
                if k == "mask":
                    flat.update({f"{key}__mask__{m}": x for m, x in v.items()})
                else:
                    flat[f"{key}__{k}"] = v
        else:
            flat[key] = value
    assert set(flat) <= set(frame["properties"])
    report = toolset.call("observe_frame", flat)
    assert len(report.report.instances_added) == 3


async def test_a_call_answers_the_same_text_through_both_faces(tmp_path, toolset):
    async with Client(build_server(config(tmp_path / "served"))) as client:
        await client.call_tool("observe_frame", frame_args())
        served = await client.call_tool("find_instance", {"query": "blue office chair"})
        summary = await client.call_tool("map_summary", {"include_image": True})
    await toolset.acall("observe_frame", frame_args())
    local = await toolset.acall("find_instance", {"query": "blue office chair"})
    assert as_text(local) == served.content[0].text
    assert local.model_dump(mode="json") == served.structured_content
    shown = await toolset.acall("map_summary", {"include_image": True})
    assert isinstance(shown, ImageResult) and len(shown.images) == 1
    assert shown.images[0].to_pil().size[0] > 0
    served_texts = [c.text for c in summary.content if c.type == "text"]
    assert shown.data is not None
    assert [json.loads(served_texts[0])["summary"]["instances"]] == [shown.data.summary.instances]
    assert as_text(shown) == "\n".join(served_texts)  # the same text blocks in process
    assert len([c for c in summary.content if c.type == "image"]) == 1


def test_sync_functions_work_positionally_and_by_keyword(toolset):
    fns = {f.__name__: f for f in toolset.functions()}
    assert fns["list_maps"]().maps == []
    assert fns["find_instance"]("a chair", 2).query == "a chair"
    assert fns["find_instance"](query="a chair", top_k=2).hits == []


# Bad input as frameworks send it: accepted when unambiguous, else an error naming it.
ACCEPTED = [
    ("find_instance", {"query": "chair", "top_k": "3"}),  # a string for a number
    ("find_instance", {"query": "chair", "session": None}),  # null for omitted
    ("find_instance", {"query": "chair", "topK": 3}),  # camelCase of top_k
    ("what_is_at", {"x": "0.5", "y": 0, "radius": None}),
    ("map_summary", {"include_image": "false"}),
    ("render_view", {"target": "map", "width": None, "unit_id": None}),
]
REFUSED = [
    ("find_instance", {"query": "chair", "top_k": "three"}, "top_k: Input should be a valid"),
    ("find_instance", {"query": None}, "query: required, but not given"),
    ("find_instance", {"query": "c", "tpo_k": 3}, "no argument 'tpo_k' (did you mean 'top_k'?)"),
    ("find_instance", {"query": "c", "top_k": 3, "topK": 4}, "'top_k' is given twice"),
    ("what_is_at", {"x": [1], "y": 0}, "x: Input should be a valid number"),
    ("render_view", {"target": "map", "width": 8}, "width=8: give 0 (the default) or"),
    ("new_map", {"session": "s" * 65}, "session: Value error, a session handle has at most 64"),
]


@pytest.mark.parametrize(("tool", "args"), ACCEPTED)
async def test_unambiguous_bad_input_is_accepted_by_both_faces(tmp_path, toolset, tool, args):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        served = await client.call_tool(tool, args)
    await toolset.acall("observe_frame", frame_args())
    await toolset.acall(tool, args)  # raises if refused
    assert not served.is_error, served.content[0].text


@pytest.mark.parametrize(("tool", "args", "message"), REFUSED)
async def test_ambiguous_bad_input_is_a_clear_error_from_both_faces(
    tmp_path, toolset, tool, args, message
):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        served = await client.call_tool(tool, args)
    await toolset.acall("observe_frame", frame_args())
    with pytest.raises(InvalidInputError) as raised:
        await toolset.acall(tool, args)
    assert served.is_error
    assert message in served.content[0].text
    assert message in str(raised.value)


def test_pydantic_ai_agent_calls_the_in_process_tools(toolset):
    pytest.importorskip("pydantic_ai")
    from pydantic_ai import Agent
    from pydantic_ai.models.test import TestModel

    toolset.call("observe_frame", frame_args())
    model = TestModel(call_tools=["list_maps", "map_summary", "describe_unit"])
    agent = Agent(model, tools=toolset.as_pydantic_ai_tools())
    result = agent.run_sync("What is mapped?")
    returns = {
        p.tool_name: p.content
        for m in result.all_messages()
        for p in getattr(m, "parts", [])
        if p.part_kind == "tool-return"
    }
    assert returns["list_maps"] == "maps: none"
    assert '"instances":3' in returns["map_summary"][0]  # text, then the top-down image
    assert returns["map_summary"][1].media_type == "image/png"
    names = {t.name for t in model.last_model_request_parameters.function_tools}
    assert names == set(TOOL_NAMES)


def test_pydantic_ai_takes_the_plain_functions_too(toolset):
    pytest.importorskip("pydantic_ai")
    from pydantic_ai import Agent
    from pydantic_ai.models.test import TestModel

    model = TestModel(call_tools=["list_maps"])
    result = Agent(model, tools=toolset.functions()).run_sync("list the maps")
    tools = {t.name: t for t in model.last_model_request_parameters.function_tools}
    assert tools["find_instance"].description.startswith("Find objects by description")
    assert "list_maps" in result.output


def test_an_unknown_tool_name_lists_the_tools(tmp_path):
    with pytest.raises(Exception, match="no tool 'find_object'; the tools are observe_frame"):
        Toolset(config(tmp_path), tools=["find_object"])


def test_langchain_tools_return_the_text_and_the_result_as_artifact(toolset):
    pytest.importorskip("langchain_core")
    tools = {t.name: t for t in toolset.as_langchain_tools()}
    call = {"type": "tool_call", "id": "1", "name": "find_instance", "args": {"query": "chair"}}
    message = tools["find_instance"].invoke(call)
    assert message.content.startswith("query: chair") and message.artifact.query == "chair"
    bad = tools["find_instance"].invoke({**call, "args": {"query": "chair", "top_k": 0}})
    assert "top_k: Input should be greater than or equal to 1" in bad.content


def test_smolagents_tools_mark_optional_arguments_nullable_and_return_text(toolset):
    pytest.importorskip("smolagents")
    tools = {t.name: t for t in toolset.as_smolagents_tools()}
    find = tools["find_instance"]
    assert find.inputs["top_k"] == {
        "type": "integer",
        "description": "hits to return (default 5)",
        "nullable": True,
    }
    assert "nullable" not in find.inputs["query"]
    assert find(query="chair", top_k=2).startswith("query: chair")


# The fewest arguments each tool takes: its required ones (issue 13.4).
REQUIRED_ONLY = {
    "find_instance": {"query": "chair"},
    "find_region": {"query": "dining"},
    "what_is_at": {"x": 0, "y": 0},
    "describe_unit": {"id": 1},
    "label_segments": {"frame": "nope", "labels": []},
    "save_map": {"name": "kept"},
    "load_map": {"name": "kept"},
    "render_view": {"target": "map"},
    "export_ply": {"name": "kept"},
    "sim_step": {"action": "turn_left"},
}


def test_every_tool_runs_with_only_its_required_arguments(toolset):
    from glmap_tools.errors import GLMapError

    toolset.call("observe_frame", {k: v for k, v in frame_args().items() if k != "annotations"})
    toolset.call("observe_frame", frame_args())
    refused = {}
    for name in [n for n in TOOL_NAMES if n != "new_map"] + ["new_map"]:  # new_map empties
        required = toolset.input_schema(name).get("required", [])
        args = frame_args() if name == "observe_frame" else REQUIRED_ONLY.get(name, {})
        assert sorted(args) == sorted(required) or name == "observe_frame", name
        try:
            toolset.call(name, args)
        except GLMapError as exc:  # a clear refusal, never a crash
            refused[name] = str(exc)
    assert set(refused) == {"label_segments", "navigate_to", "locate_situation"}, refused
    assert "give either x and y, or unit_id" in refused["navigate_to"]
    assert "give the situation text" in refused["locate_situation"]  # or a reading
