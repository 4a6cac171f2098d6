"""Sessions under pressure (dropped sessions are told, busy ones are kept) and what
list_maps and load errors reveal about the server's files."""

from __future__ import annotations

import json

import pytest
from mcp import Client

from glmap_tools.app.state import SessionRegistry
from glmap_tools.errors import StoreError, UnknownIdError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def test_a_connection_whose_session_was_dropped_is_told_and_new_map_starts_it_again(tmp_path):
    registry = SessionRegistry(
        config(tmp_path, max_sessions=2, session_protect_s=0), HashingEmbedder()
    )
    first = registry.resolve(None, "connection-a")
    registry.start_session()
    registry.start_session()  # room for it: connection-a's session (idle longest) goes
    with pytest.raises(UnknownIdError, match="this connection's session was dropped"):
        registry.resolve(None, "connection-a")
    with pytest.raises(UnknownIdError, match="was dropped"):
        registry.resolve(first.handle, None)
    again = registry.resolve(None, "connection-a", restart=True)  # what new_map/load_map do
    assert again.handle != first.handle and not again.live.glmap.instances
    assert registry.resolve(None, "connection-a") is again
    registry.close()


def test_one_client_starting_sessions_cannot_drop_a_session_in_use(tmp_path):
    registry = SessionRegistry(config(tmp_path, max_sessions=4), HashingEmbedder())
    working = registry.resolve(None, "connection-a")
    for _ in range(3):
        registry.start_session()
    with pytest.raises(StoreError, match="reuse your session handle"):
        registry.start_session()
    assert registry.resolve(None, "connection-a") is working
    registry.close()


async def test_the_default_session_can_be_named_from_the_first_call(tmp_path):
    async with Client(build_server(config(tmp_path))) as client:
        named = await client.call_tool("observe_frame", {**frame_args(), "session": "default"})
        plain = await client.call_tool("find_instance", {"query": "chair"})
    assert not named.is_error, named.content[0].text
    assert named.structured_content["session"] == "default"
    assert plain.structured_content["hits"]  # the frame went into the default session's map


def test_with_a_pinned_map_every_connection_works_on_it_unless_it_names_a_session(tmp_path):
    registry = SessionRegistry(config(tmp_path, map_name="flat-3"), HashingEmbedder())
    a, b = registry.resolve(None, "connection-a"), registry.resolve(None, "connection-b")
    own = registry.start_session()
    assert a is b and a.handle == "default" and registry.resolve("default", None) is a
    assert registry.resolve(own.handle, "connection-a") is own
    registry.close()


async def test_list_maps_shows_only_map_files_in_the_maps_folder_never_symlinked_ones(tmp_path):
    outside = tmp_path / "secret.txt"
    outside.write_text("x" * 12345)
    maps = tmp_path / "maps"
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("observe_frame", frame_args())
        assert not (await client.call_tool("save_map", {"name": "real"})).is_error
        (maps / "leak.glmap").symlink_to(outside)
        (maps / "loop.glmap").symlink_to(maps / "real.glmap")
        (maps / "folder.glmap").mkdir()
        listed = await client.call_tool("list_maps", {})
        resource = await client.read_resource("glmap://maps")
        loaded = await client.call_tool("load_map", {"name": "leak"})
    names = [m["name"] for m in listed.structured_content["maps"]]
    assert names == ["real"]
    assert "12345" not in listed.content[0].text
    assert json.loads(resource.contents[0].text) == ["real"]
    assert loaded.is_error and "outside the maps folder" in loaded.content[0].text


async def test_a_load_error_names_the_map_but_not_the_servers_folder(tmp_path):
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "broken.glmap").write_bytes(b"this is not a SQLite file" * 100)
    async with Client(build_server(config(tmp_path))) as client:
        result = await client.call_tool("load_map", {"name": "broken"})
    text = result.content[0].text
    assert result.is_error and "broken" in text
    assert str(tmp_path) not in text and "/maps" not in text
