"""Render quality on the real Redwood frames: a map of frames 0-3 seen from frame 4."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.ingest.cli import bundled_folder
from glmap_tools.ingest.datasets import open_sequence
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.views import select_view, write_png
from glmap_tools.views.quality import coverage_psnr, render_against, side_by_side

# Measured with `python -m glmap_tools.bench views` (see glmap_tools/views/design.md):
# tau -5: 25.6 dB own colour, 18.0 dB composited, 65 % covered;
# tau -20: 24.7 dB, 21.4 dB, 70 %. The floors sit a little under the lower of the two.
PSNR_FLOOR = 23.5  # dB
PSNR_COMPOSITED_FLOOR = 16.5  # dB
COVERAGE_FLOOR = 0.55


@pytest.fixture(scope="module")
def frames():
    return list(open_sequence(bundled_folder()).frames())


@pytest.mark.parametrize("tau", [-5.0, -20.0])
def test_a_map_of_frames_0_to_3_renders_frame_4_above_the_psnr_floor(frames, tau, tmp_path):
    glmap = GLMap(MapConfig(estimator={"tau": tau}), embedder=HashingEmbedder())
    for item in frames[:4]:
        glmap.integrate(item.frame, item.semantics, item.index)
    held_out = frames[4].frame
    score, view = render_against(glmap, held_out.pose, held_out.intrinsics, held_out.rgb)
    write_png(tmp_path / "rendered.png", view.rgb)
    write_png(tmp_path / "real.png", held_out.rgb)
    write_png(tmp_path / "side_by_side.png", side_by_side(view, held_out.rgb))
    assert len(list(tmp_path.glob("*.png"))) == 3
    assert score.psnr > PSNR_FLOOR, score
    assert score.psnr_composited > PSNR_COMPOSITED_FLOOR, score
    assert score.coverage > COVERAGE_FLOOR, score
    # A shuffled real image scores far lower: the floor measures the map, not luck.
    rng = np.random.default_rng(0)
    shuffled = held_out.rgb.reshape(-1, 3)[rng.permutation(held_out.rgb[..., 0].size)]
    worse = coverage_psnr(view, shuffled.reshape(held_out.rgb.shape))
    assert worse.psnr < score.psnr - 5.0


def test_every_redwood_unit_gets_a_view_in_seen_free_space(frames):
    glmap = GLMap(MapConfig(), embedder=HashingEmbedder())
    for item in frames:
        glmap.integrate(item.frame, item.semantics, item.index)
    for uid in sorted(glmap.instances) + sorted(glmap.regions):
        choice = select_view(glmap, uid)
        assert choice.placement == "free", choice.note
        assert choice.visible > 0.8, choice.note
