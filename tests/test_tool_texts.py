"""What a client reads from the simulator, navigation and situated-QA tools stays as
recorded in tests/data/tool_texts.json (written by `python -m tests.tool_texts`)."""

from __future__ import annotations

import json
import os

import pytest

from tests.tool_texts import GOLDEN, record

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = [pytest.mark.slow, pytest.mark.anyio]  # plays four short episodes


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_each_tool_call_reads_as_recorded_text_block_for_text_block():
    want = json.loads(GOLDEN.read_text())
    got = await record()
    assert [(r["call"], r["args"]) for r in got] == [(r["call"], r["args"]) for r in want]
    for k, (g, w) in enumerate(zip(got, want, strict=True)):
        assert g == w, f"call {k}: {w['call']}({w['args']})"
