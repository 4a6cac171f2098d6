"""`glmap demo` end to end (short episode, hashing embedder): the GLMap agent plays, a
report with value maps and a transcript of every call are written."""

from __future__ import annotations

import json
import os
import re

import pytest

from glmap_tools.server import demo

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_the_demo_episode_is_driven_by_the_glmap_agent_and_reported_with_value_maps(
    tmp_path, capsys
):
    out = tmp_path / "demo"
    assert await demo.run(out, scene=0, seed=1, embedder="hashing", max_steps=9) == 0
    trace = [json.loads(line) for line in (out / "episode" / "trace.jsonl").open()]
    assert trace[0]["tool"] == "sim_reset"
    steps = [c for c in trace[1:] if c["tool"] == "nav_step"]
    assert steps and len(steps) == len(trace) - 1  # every action chosen by the GLMap policy
    assert all(c["arguments"]["policy"] == "glmap" for c in steps)
    report = (out / "episode" / "report.md").read_text()
    value_maps = re.findall(r"\]\((images/\d+_nav_step_2\.png)\)", report)
    assert len(value_maps) >= 2
    for image in value_maps:
        assert (out / "episode" / image).stat().st_size > 2000

    md = (out / "transcript.md").read_text()
    page = (out / "transcript.html").read_text()
    assert "played by the GLMap agent" in md and "episode/report.html" in md
    assert "<a href='episode/report.html'>" in page and "](" not in page  # links, not Markdown
    assert "colour bar" in (out / "episode" / "report.html").read_text()  # the legend
    shown = re.findall(r"\]\((episode/images/[^)]+\.png)\)", md)
    assert shown and all(f"src='{i}'" in page for i in shown)
    called = re.findall(r"^## \d+\. `(\w+)`", md, flags=re.M)
    for tool in ("find_instance", "find_region", "value_map", "render_view", "export_ply"):
        assert tool in called, tool
    linked = re.findall(r"\]\((images/[^)]+)\)", md)
    assert len(linked) >= 4
    for image in linked:
        assert (out / image).stat().st_size > 500, image
        assert f"src='{image}'" in page
    assert (out / "maps" / "demo.glmap").is_file()
    assert (out / "maps" / "demo.ply").stat().st_size > 1000
    assert "Episode result:" in capsys.readouterr().out
