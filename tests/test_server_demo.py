"""`glmap demo` end to end (short tour, hashing embedder): it writes its folder."""

from __future__ import annotations

import os
import re

import pytest

from glmap_tools.server import demo

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_the_demo_writes_images_and_a_transcript_of_every_call(tmp_path, capsys):
    out = tmp_path / "demo"
    assert await demo.run(out, scene=0, seed=1, embedder="hashing", max_steps=16) == 0
    md = (out / "transcript.md").read_text()
    page = (out / "transcript.html").read_text()
    called = re.findall(r"^## \d+\. `(\w+)`", md, flags=re.M)
    for tool in ("sim_reset", "sim_step", "find_instance", "find_region", "render_view"):
        assert tool in called, tool
    assert "what_is_at" in called and "describe_unit" in called
    linked = re.findall(r"\]\((images/[^)]+)\)", md)
    assert len(linked) >= 6
    for image in linked:
        assert (out / image).stat().st_size > 500, image
        assert f"src='{image}'" in page
    assert (out / "maps" / "demo.glmap").is_file()
    assert "export_ply" in called and (out / "maps" / "demo.ply").stat().st_size > 1000
    assert "Episode result:" in capsys.readouterr().out
