"""What a model pays for: a lean tools/list and compact results (bytes measured by
`python -m glmap_tools.bench tokens`)."""

from __future__ import annotations

import json

import pytest
from mcp import Client

from glmap_tools.app.results import compact_schema, compact_text
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_tools_list_has_no_output_schemas_titles_or_wrapped_docstrings(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        tools = (await client.list_tools()).tools
    sent = json.dumps([t.model_dump(mode="json", by_alias=True, exclude_none=True) for t in tools])
    assert all(t.output_schema is None for t in tools)
    assert '"title"' not in sent and "        " not in sent
    sessions = [t.input_schema["properties"]["session"] for t in tools if t.name != "list_maps"]
    assert sum("description" in s for s in sessions) == 1  # said once, not per tool
    observe = next(t for t in tools if t.name == "observe_frame").input_schema
    assert "anyOf" not in json.dumps(observe["properties"]["annotations"])  # optional, not null


async def test_a_result_is_compact_text_beside_exact_structured_content(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        found = await client.call_tool("find_instance", {"query": "blue office chair"})
    text = found.content[0].text
    best = found.structured_content["hits"][0]
    assert text.startswith("query: ") and "\n- id=" in text and "\n  " not in text
    with pytest.raises(json.JSONDecodeError):
        json.loads(text)  # not a JSON copy of the structured content
    assert 'description="a blue office chair"' in text
    assert (
        f"centroid=[{','.join(f'{c:.3f}'.rstrip('0').rstrip('.') for c in best['centroid'])}]"
        in (text)
    )
    assert len(text) < len(json.dumps(found.structured_content))


def test_compact_text_and_schema_drop_nothing_a_reader_needs():
    text = compact_text(
        {"query": "a chair", "hits": [{"id": 3, "score": 0.81234, "note": None, "ids": []}],
         "maps": [], "flag": False}
    )  # fmt: skip
    assert text == 'query: "a chair"\nhits:\n- id=3 score=0.812\nmaps: none\nflag: false'
    schema = {
        "title": "args",
        "properties": {
            "title": {"title": "Title", "type": "string"},
            "limit": {"anyOf": [{"type": "integer"}, {"type": "null"}], "default": None},
            "id": {"type": "integer", "maximum": 2**62, "minimum": 1},
        },
    }
    assert compact_schema(schema) == {
        "properties": {
            "title": {"type": "string"},
            "limit": {"type": "integer"},
            "id": {"type": "integer", "minimum": 1},
        }
    }


async def test_tools_list_fits_the_12_kb_budget(tmp_path):
    from glmap_tools.bench.tokens import TOOLS_LIST_TARGET_BYTES, compact

    async with Client(build_server(config(tmp_path))) as client:
        tools = (await client.list_tools()).tools
    sent = {"tools": [t.model_dump(mode="json", by_alias=True, exclude_none=True) for t in tools]}
    assert len(tools) == 21
    assert compact(sent) <= TOOLS_LIST_TARGET_BYTES


def test_limits_are_checked_but_not_listed():
    schema = {"type": "string", "maxLength": 64, "items": {"maximum": 1e4, "minimum": 1}}
    assert compact_schema(schema) == {"type": "string", "items": {"minimum": 1}}
