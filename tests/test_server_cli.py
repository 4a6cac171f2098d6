"""glmap-mcp's command line: the options the README and docs name are accepted."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest

from glmap_tools.server.cli import build_parser, perception_from_args


@pytest.mark.parametrize("name", ["pending", "geometric"])
def test_model_free_perception_leaves_the_naming_to_the_calling_agent(name):
    args = build_parser().parse_args(["--perception", name])
    assert perception_from_args(args) is None  # segments wait for label_segments


def test_an_unknown_perception_is_refused_naming_the_choices(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--perception", "magic"])
    err = capsys.readouterr().err
    assert "'magic'" in err and "geometric" in err and "mllm" in err


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--max-frame-mb", "inf"], "--max-frame-mb inf: give megabytes"),  # was OverflowError
        (["--max-frame-mb", "nan"], "--max-frame-mb nan: give megabytes"),
        (["--llm-timeout", "nan"], "(--llm-timeout) must be in (0, 3600]"),  # was accepted
        (["--llm-timeout", "-1"], "(--llm-timeout) must be in (0, 3600]"),
        (["--threads", str(10**23)], "must be an integer in 1..1024"),  # was a ctypes error
    ],
)
def test_an_out_of_range_number_is_refused_naming_the_option(argv, said, tmp_path):
    from glmap_tools.errors import InvalidInputError
    from glmap_tools.server.cli import config_from_args

    args = build_parser().parse_args([*argv, "--maps-dir", str(tmp_path)])
    with pytest.raises(InvalidInputError) as refused:
        config_from_args(args)  # what main() reports as "glmap-mcp: error: ..."
    assert said in str(refused.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow  # loads MiniLM, whose teardown was what kept the process
def test_glmap_mcp_exits_within_a_second_of_stdin_closing_after_a_call(tmp_path):
    """Per-call clients (mcp 1.x LangChain, smolagents) wait 2 s, then kill the server."""
    server = subprocess.Popen(
        [sys.executable, "-m", "glmap_tools.server", "--maps-dir", str(tmp_path)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    assert server.stdin is not None and server.stdout is not None

    def send(message: dict) -> None:  # type: ignore[type-arg]
        server.stdin.write((json.dumps(message) + "\n").encode())  # type: ignore[union-attr]
        server.stdin.flush()  # type: ignore[union-attr]

    hello = {"protocolVersion": "2025-06-18", "capabilities": {}, "clientInfo": {"name": "t"}}
    send({"jsonrpc": "2.0", "id": 1, "method": "initialize", "params": hello})
    server.stdout.readline()
    send({"jsonrpc": "2.0", "method": "notifications/initialized"})
    find = {"name": "find_instance", "arguments": {"query": "a chair"}}
    send({"jsonrpc": "2.0", "id": 2, "method": "tools/call", "params": find})
    while json.loads(server.stdout.readline()).get("id") != 2:
        pass
    start = time.monotonic()
    server.stdin.close()
    assert server.wait(timeout=30) == 0
    assert time.monotonic() - start < 1.0
