"""`glmap-mcp` over stdio answers the handshake from prepared answers while the SDK imports.

Each test launches the real console script with its own $GLMAP_CACHE_DIR. How soon the
answers come is measured by `python -m glmap_tools.bench startup`, not here.
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import anyio
import pytest
from mcp import Client
from mcp.client.stdio import StdioServerParameters

from glmap_tools.bench.startup import StdioPeer
from glmap_tools.server.handshake import (
    FORMAT,
    HANDSHAKE_VERSIONS,
    MODERN_VERSIONS,
    PreparedAnswers,
    StdioRelay,
    opening_requests,
    source_stamp,
)
from tests.test_server_transports import FAST, REPO, STARTUP_TIMEOUT, server_command

VERSION = "2025-11-25"
MARKER = "prepared answer from the handshake file"


def launch(tmp_path: Path, cache: Path) -> StdioPeer:
    env = dict(os.environ, GLMAP_CACHE_DIR=str(cache), HF_HUB_OFFLINE="1")
    return StdioPeer([*server_command(), *FAST, "--maps-dir", str(tmp_path / "maps")], env)


def handshake(peer: StdioPeer, version: str = VERSION) -> tuple[dict[str, Any], dict[str, Any]]:
    """(opening result, tools/list result) as the client received them: `initialize` for
    handshake-era versions, `server/discover` for stateless ones."""
    (opening, _), (listed, _) = peer.open(version, STARTUP_TIMEOUT, client="test")
    return opening["result"], listed["result"]


def call(
    peer: StdioPeer, request_id: int, name: str | None, arguments: dict[str, Any], version: str
) -> Any:
    """The answer to tools/call `name` (None: to tools/list), in `version`'s form."""
    params: dict[str, Any] = {"name": name, "arguments": arguments} if name else {}
    if version in MODERN_VERSIONS:
        params["_meta"] = opening_requests(version, "test")[-1]["params"]["_meta"]
    method = "tools/call" if name else "tools/list"
    peer.send({"jsonrpc": "2.0", "id": request_id, "method": method, "params": params})
    return peer.answer(request_id, STARTUP_TIMEOUT)[0]


def stored(cache: Path) -> dict[str, Any]:
    return json.loads((cache / "handshake.json").read_text())


@pytest.fixture(scope="module")
def first(tmp_path_factory) -> tuple[Path, dict[str, tuple[dict[str, Any], dict[str, Any]]]]:
    """A cache folder filled by first launches (one per opening), and their SDK-made answers."""
    tmp = tmp_path_factory.mktemp("first")
    cache = tmp / "cache"
    answers = {}
    for version in (VERSION, MODERN_VERSIONS[0]):
        peer = launch(tmp, cache)
        try:
            answers[version] = handshake(peer, version)
        finally:
            peer.close()
    return cache, answers


@pytest.fixture
def prepared(first) -> tuple[Path, dict[str, Any], dict[str, Any]]:
    cache, answers = first
    return cache, *answers[VERSION]


def test_a_first_launch_answers_through_the_sdk_and_keeps_its_answers(first):
    cache, answers = first
    data = stored(cache)
    assert data["format"] == FORMAT
    mine = data["installations"][source_stamp()]["answers"]
    init, listed = answers[VERSION]
    assert mine[VERSION] == {"initialize": init, "tools/list": listed}
    assert init["protocolVersion"] == VERSION and init["serverInfo"]["name"] == "glmap"
    assert "find_instance" in {t["name"] for t in listed["tools"]}
    modern = MODERN_VERSIONS[0]
    discovered, modern_list = answers[modern]
    assert mine[modern] == {"server/discover": discovered, "tools/list": modern_list}
    assert {t["name"] for t in modern_list["tools"]} == {t["name"] for t in listed["tools"]}


@pytest.mark.parametrize("version", [VERSION, MODERN_VERSIONS[0]])
def test_a_later_launch_answers_from_the_file_and_the_sdk_session_follows(first, tmp_path, version):
    cache, answers = first
    opening, listed = answers[version]
    here = tmp_path / "cache"
    here.mkdir()
    data = stored(cache)
    stale = json.loads(json.dumps(listed))
    stale["tools"][0]["description"] = MARKER  # only the file says this
    data["installations"][source_stamp()]["answers"][version]["tools/list"] = stale
    (here / "handshake.json").write_text(json.dumps(data))
    peer = launch(tmp_path, here)
    try:
        got_opening, got_list = handshake(peer, version)
        assert got_opening == opening
        assert got_list["tools"][0]["description"] == MARKER  # answered before the SDK
        summary = call(peer, 3, "map_summary", {}, version)  # the SDK's session follows
        assert not summary["result"].get("isError"), summary
        relisted = call(peer, 4, None, {}, version)
        assert relisted["result"] == listed  # later requests: the SDK itself
    finally:
        peer.close()
    assert "prepared tools/list answer was out of date" in "".join(peer.stderr)
    refreshed = stored(here)["installations"][source_stamp()]["answers"]
    assert refreshed[version]["tools/list"] == listed


def test_answers_of_another_installation_are_not_used(prepared, tmp_path):
    cache, _, listed = prepared
    here = tmp_path / "cache"
    here.mkdir()
    data = stored(cache)
    other = data["installations"].pop(source_stamp())
    other["answers"][VERSION]["tools/list"]["tools"][0]["description"] = MARKER
    data["installations"]["another-installation"] = other
    (here / "handshake.json").write_text(json.dumps(data))
    peer = launch(tmp_path, here)
    try:
        _, got_list = handshake(peer)
    finally:
        peer.close()
    assert got_list == listed
    kept = stored(here)["installations"]  # both installations' answers are kept
    assert set(kept) == {"another-installation", source_stamp()}


def test_a_version_without_prepared_answers_is_negotiated_by_the_sdk(prepared, tmp_path):
    cache, _, listed = prepared
    here = tmp_path / "cache"
    here.mkdir()
    (here / "handshake.json").write_text((cache / "handshake.json").read_text())
    peer = launch(tmp_path, here)
    try:
        init, got_list = handshake(peer, "1999-01-01")
    finally:
        peer.close()
    assert init["protocolVersion"] in HANDSHAKE_VERSIONS  # the SDK's counter-offer
    assert "find_instance" in {t["name"] for t in got_list["tools"]}


@pytest.mark.anyio
async def test_a_real_client_session_works_on_prepared_answers(prepared, tmp_path):
    cache, _, _ = prepared
    command = server_command()
    params = StdioServerParameters(
        command=command[0],
        args=[*command[1:], *FAST, "--maps-dir", str(tmp_path / "maps")],
        cwd=str(REPO),
        env=dict(os.environ, GLMAP_CACHE_DIR=str(cache)),
    )
    with anyio.fail_after(STARTUP_TIMEOUT):
        async with Client(params) as client:
            tools = {t.name for t in (await client.list_tools()).tools}
            found = await client.call_tool("find_instance", {"query": "a chair"})
    assert "observe_frame" in tools and not found.is_error


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def test_the_command_line_imports_neither_the_sdk_nor_pydantic():
    """What runs before the relay answers the handshake stays light."""
    code = (
        "import sys\n"
        "import glmap_tools.server.cli, glmap_tools.server.handshake\n"
        "print(' '.join(m for m in ('mcp', 'mcp_types', 'pydantic', 'uvicorn', 'scipy') "
        "if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert done.stdout.strip() == "", done.stdout


def messages_until(peer: StdioPeer, request_id: int) -> list[dict[str, Any]]:
    """Every message the server sends up to and including its answer to `request_id`."""
    seen: list[dict[str, Any]] = []
    while not seen or seen[-1].get("id") != request_id or "method" in seen[-1]:
        line = peer.lines.get(timeout=STARTUP_TIMEOUT)
        assert line, "the server exited:\n" + "".join(peer.stderr[-20:])
        seen.append(json.loads(line))
    return seen


@pytest.mark.parametrize("version", [VERSION, MODERN_VERSIONS[0]])
def test_every_request_gets_exactly_one_answer_through_the_relay(prepared, tmp_path, version):
    """Prepared answers stand in for the SDK's: never both, and a paginated tools/list
    (a cursor the prepared answer cannot know) is the SDK's alone."""
    cache = prepared[0]
    peer = launch(tmp_path, cache)
    first, *rest = opening_requests(version, "test")
    meta = rest[-1]["params"].get("_meta")
    paged = {"cursor": "page-2", **({"_meta": meta} if meta else {})}
    summary = {"name": "map_summary", "arguments": {}, **({"_meta": meta} if meta else {})}
    seen: list[dict[str, Any]] = []
    try:
        peer.send(first)
        if version not in MODERN_VERSIONS:
            seen += messages_until(peer, 1)
        for message in rest:
            peer.send(message)
        peer.send({"jsonrpc": "2.0", "id": 3, "method": "tools/list", "params": paged})
        peer.send({"jsonrpc": "2.0", "id": 4, "method": "tools/call", "params": summary})
        while not {1, 2, 3, 4} <= {m.get("id") for m in seen if "method" not in m}:
            line = peer.lines.get(timeout=STARTUP_TIMEOUT)
            assert line, "the server exited:\n" + "".join(peer.stderr[-20:])
            seen.append(json.loads(line))
    finally:
        peer.close()
    while not peer.lines.empty():  # anything sent after the last answer
        line = peer.lines.get()
        if line:
            seen.append(json.loads(line))
    answered = sorted(m["id"] for m in seen if "id" in m and "method" not in m)
    assert answered == [1, 2, 3, 4]  # one answer each, none twice
    by_id = {m["id"]: m for m in seen if "id" in m and "method" not in m}
    assert "result" in by_id[3] or "error" in by_id[3]
    assert not by_id[4]["result"].get("isError"), by_id[4]


def test_a_first_tools_list_with_a_cursor_is_left_to_the_sdk(tmp_path):
    """A page the prepared answer cannot know: the relay answers only the opening early."""
    answers = PreparedAnswers(tmp_path / "answers.json", "stamp")
    answers.put(VERSION, "initialize", {"protocolVersion": VERSION, "capabilities": {}})
    answers.put(VERSION, "tools/list", {"tools": []})
    lines = [
        {"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": {"protocolVersion": VERSION}},
        {"jsonrpc": "2.0", "method": "notifications/initialized"},
        {"jsonrpc": "2.0", "id": 2, "method": "tools/list", "params": {"cursor": "page-2"}},
    ]
    source = io.BytesIO(b"".join(json.dumps(m).encode() + b"\n" for m in lines))
    sink = io.BytesIO()
    relay = StdioRelay(answers, source=source, sink=sink)
    while relay.lines.get(timeout=10) is not None:
        pass  # every client line read (and looked at)
    sent = [json.loads(line) for line in sink.getvalue().splitlines()]
    assert [m["id"] for m in sent] == [1]
    assert relay.answered_early == ["initialize"]


def test_a_malformed_line_before_tools_list_leaves_the_relay_reading(tmp_path):
    """A line nested too deep to parse, or a request whose id is a list or an object, is the
    SDK's to answer; the relay reads on and still answers the handshake early."""
    answers = PreparedAnswers(tmp_path / "answers.json", "stamp")
    answers.put(VERSION, "initialize", {"protocolVersion": VERSION, "capabilities": {}})
    answers.put(VERSION, "tools/list", {"tools": []})
    opening = {"jsonrpc": "2.0", "id": 1, "method": "initialize"}
    lines = [
        b'{"a":' * 50_000,
        b"[" * 100_000,
        json.dumps({**opening, "id": [1], "params": {"protocolVersion": VERSION}}).encode(),
        json.dumps({**opening, "params": {"protocolVersion": VERSION}}).encode(),
        json.dumps({"jsonrpc": "2.0", "id": {"a": 1}, "method": "tools/list"}).encode(),
        json.dumps({"jsonrpc": "2.0", "id": True, "method": "tools/list"}).encode(),
        json.dumps({"jsonrpc": "2.0", "id": 2, "method": "tools/list"}).encode(),
    ]
    source = io.BytesIO(b"".join(line + b"\n" for line in lines))
    sink = io.BytesIO()
    relay = StdioRelay(answers, source=source, sink=sink)
    got = []
    while (line := relay.lines.get(timeout=10)) is not None:
        got.append(line)
    assert len(got) == len(lines)  # every line passed on to the SDK
    sent = [json.loads(line) for line in sink.getvalue().splitlines()]
    assert [m["id"] for m in sent] == [1, 2]
    assert relay.answered_early == ["initialize", "tools/list"]
