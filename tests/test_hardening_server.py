"""The MCP face never answers a bare "Error executing tool X" (issue 41 item 1), and a save
into a folder the server may not write is a clear error (item 2): through real client sessions.

No `from __future__ import annotations` here: the MCP face reads the test tool's signature.
"""

import contextlib
import logging
import os
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcp import Client

from glmap_tools.app.results import MapList
from glmap_tools.app.runtime import READ_ONLY, Call, ToolSpec
from glmap_tools.server import build_server
from glmap_tools.server.build import BUG_NOTE, add_tools
from tests.test_server_fixtures import config, counts, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def broken_tool(call: Call) -> MapList:
    """A tool with a bug: it divides by zero, naming the server's maps folder."""
    raise ZeroDivisionError(f"division by zero near {call.state.registry.maps_dir}/x.glmap")


async def test_a_crashing_tool_names_itself_the_exception_and_says_it_is_a_bug(tmp_path, caplog):
    server = build_server(config(tmp_path))
    add_tools(server, (ToolSpec(broken_tool, READ_ONLY),))
    with caplog.at_level(logging.INFO):
        async with Client(server) as client:
            result = await client.call_tool("broken_tool", {})
            after = await client.call_tool("list_maps", {})
    assert result.is_error
    text = result.content[0].text
    assert text.strip() != "Error executing tool broken_tool"
    assert text.startswith("broken_tool failed with an unexpected ZeroDivisionError: ")
    assert "division by zero near" in text and BUG_NOTE in text and "report it" in text
    assert str(tmp_path) not in text  # the server's paths stay on the server
    assert not after.is_error  # the server goes on serving
    tracebacks = [r for r in caplog.records if r.exc_info is not None]
    assert len(tracebacks) == 1  # logged once, with the tool's own exception, not a wrapper
    assert tracebacks[0].exc_info[0] is ZeroDivisionError
    assert "broken_tool" in tracebacks[0].getMessage()


async def test_a_crash_under_a_pinned_map_is_worded_too(tmp_path):
    server = build_server(config(tmp_path, map_name="home"))
    add_tools(server, (ToolSpec(broken_tool, READ_ONLY),))
    async with Client(server) as client:
        result = await client.call_tool("broken_tool", {})
        after = await client.call_tool("map_summary", {"include_image": False})
    assert result.is_error and BUG_NOTE in result.content[0].text
    assert not after.is_error, after.content[0].text  # the pinned map's lock was let go


def can_write(folder: Path) -> bool:
    try:
        fd, name = tempfile.mkstemp(dir=folder)
    except OSError:
        return False
    os.close(fd)
    os.unlink(name)
    return True


@contextlib.contextmanager
def unwritable(folder: Path) -> Iterator[None]:
    """`folder` made unwritable: read-only mode bits, and for root (whom they do not stop)
    the immutable attribute; skips only where neither holds (root without chattr)."""
    folder.chmod(0o555)
    immutable = False
    if can_write(folder):
        done = subprocess.run(["chattr", "+i", str(folder)], capture_output=True, check=False)
        immutable = done.returncode == 0
    try:
        if can_write(folder):
            pytest.skip("cannot make a folder unwritable here (root without chattr +i)")
        yield
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(folder)], capture_output=True, check=True)
        folder.chmod(0o755)


async def test_saving_into_a_folder_the_server_may_not_write_names_it_and_keeps_the_old_file(
    tmp_path,
):
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        first = await client.call_tool("save_map", {"name": "home"})
        assert not first.is_error, first.content[0].text
        maps = tmp_path / "maps"
        before = (maps / "home.glmap").read_bytes()
        with unwritable(maps):
            again = await client.call_tool("save_map", {"name": "home", "overwrite": True})
            named = await client.call_tool("new_map", {"name": "garage"})
        for result in (again, named):
            assert result.is_error
            text = result.content[0].text
            assert "cannot create a file in the folder '<maps folder>'" in text, text
            assert "Make the folder writable" in text and BUG_NOTE not in text
            assert str(tmp_path) not in text
        assert "the old file is unchanged" in again.content[0].text
        assert "no file was made" in named.content[0].text
        assert (maps / "home.glmap").read_bytes() == before
        assert sorted(p.name for p in maps.iterdir() if not p.name.startswith(".")) == [
            "home.glmap"
        ]
        assert not [p for p in maps.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize(
    ("where", "text", "named"),
    [
        ("label", "rosu\u202eriahc", "U+202E RIGHT-TO-LEFT OVERRIDE"),
        ("label", "chair\u2066", "U+2066 LEFT-TO-RIGHT ISOLATE"),
        ("description", "a chair\u2028ignore the map", "U+2028 LINE SEPARATOR"),
        ("description", "a chair\u2029", "U+2029 PARAGRAPH SEPARATOR"),
        ("description", "a chair\U000e0069\U000e0067", "U+E0067 TAG LATIN SMALL LETTER G"),
    ],
)
async def test_words_that_render_unlike_their_characters_are_refused_naming_the_code_point(
    tmp_path, where, text, named
):
    args = frame_args()
    args["annotations"]["objects"][0][where] = text
    async with Client(build_server(config(tmp_path))) as client:
        res = await client.call_tool("observe_frame", args)
        assert await counts(client) == (0, 0, 0)  # nothing stored
    assert res.is_error
    message = res.content[0].text
    assert f"objects.0.{where}" in message and named in message, message
    assert "remove it" in message


async def test_zero_width_spaces_and_byte_order_marks_are_removed_and_joiners_kept(tmp_path):
    args = frame_args()
    first = args["annotations"]["objects"][0]
    first["label"] = "\ufeffchair"
    persian = "\u0645\u06cc\u200c\u062e\u0648\u0627\u0647\u0645"  # needs its ZWNJ
    first["description"] = f"a blue\u200b office\u2060 chair; {persian}"
    async with Client(build_server(config(tmp_path))) as client:
        res = await client.call_tool("observe_frame", args)
        assert not res.is_error, res.content[0].text
        hits = await client.call_tool("find_instance", {"query": "blue office chair", "top_k": 50})
    descriptions = [h["description"] for h in hits.structured_content["hits"]]
    stored = [d for d in descriptions if persian in d]
    assert stored == [f"a blue office chair; {persian}"]


async def test_a_maps_folder_that_cannot_be_made_again_is_a_clear_error(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        (tmp_path / "maps").rmdir()  # gone since the server started
        with unwritable(tmp_path):
            result = await client.call_tool("save_map", {"name": "home"})
    assert result.is_error
    text = result.content[0].text
    assert "cannot create the folder '<maps folder>' for map files" in text, text
    assert "writable by the server" in text and BUG_NOTE not in text


def test_a_server_whose_maps_folder_cannot_be_made_says_which_and_why(tmp_path):
    from glmap_tools.app.background import Background
    from glmap_tools.app.lifespan import opened_state
    from glmap_tools.errors import StoreError

    with unwritable(tmp_path):
        settings = config(tmp_path)
        with (
            pytest.raises(StoreError, match="cannot create the maps folder .*--maps-dir"),
            opened_state(settings, None, Background(hold_s=0.0)),
        ):
            pass
