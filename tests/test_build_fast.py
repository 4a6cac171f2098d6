"""The fast single-folder build (read-ahead thread, warm embeddings, one BLAS thread, one write
at the end) against the reference loop (frames in turn, a commit per frame): the same map."""

from __future__ import annotations

import shutil
import threading
from pathlib import Path

import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.ingest.build import FAST, REFERENCE, BuildSettings, build_map
from glmap_tools.ingest.cli import bundled_folder
from glmap_tools.ingest.prefetch import prefetched
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.minilm import default_embedder
from glmap_tools.map import GLMap
from tests.build_helpers import assert_same_map, write_small_tour


@pytest.fixture(scope="module")
def tour(tmp_path_factory) -> Path:
    return write_small_tour("s01", tmp_path_factory.mktemp("tour") / "s01", frames=10)


def _both(folder: Path, tmp_path: Path, settings: BuildSettings) -> tuple[Path, Path]:
    fast, ref = tmp_path / "fast.glmap", tmp_path / "ref.glmap"
    built = build_map(folder, fast, settings, pipeline=FAST)
    assert built.stats.frames == len(built.sequence)
    build_map(folder, ref, settings, pipeline=REFERENCE)
    return fast, ref


@pytest.mark.parametrize("embedder", ["minilm", "hashing"])
def test_the_fast_build_of_a_tour_is_the_reference_build(tour, tmp_path, embedder) -> None:
    fast, ref = _both(tour, tmp_path, BuildSettings(embedder=embedder))
    emb = default_embedder() if embedder == "minilm" else HashingEmbedder()
    a, b = GLMap.open(fast, embedder=emb), GLMap.open(ref, embedder=emb)
    try:
        assert len(a.instances) >= 3 and len(a.regions) >= 1
        assert_same_map(a, b)
    finally:
        a.close()
        b.close()


def test_the_fast_build_of_the_redwood_frames_with_a_stride_is_the_reference_build(tmp_path):
    settings = BuildSettings(embedder="hashing", stride=2)
    fast, ref = _both(bundled_folder(), tmp_path, settings)
    a, b = GLMap.open(fast, embedder=HashingEmbedder()), GLMap.open(ref, embedder=HashingEmbedder())
    try:
        assert len(a.trajectory) == 3
        assert_same_map(a, b)
    finally:
        a.close()
        b.close()


def test_a_build_that_fails_on_a_bad_frame_leaves_no_file_behind(tour, tmp_path) -> None:
    folder = tmp_path / "broken"
    shutil.copytree(tour, folder)
    (folder / "depth" / "00004.png").write_bytes(b"not a png")
    for pipeline in (FAST, REFERENCE):
        out = tmp_path / "out" / "m.glmap"
        with pytest.raises(InvalidInputError, match="00004.png"):
            build_map(folder, out, BuildSettings(embedder="hashing"), pipeline=pipeline)
        assert list((tmp_path / "out").iterdir()) == []  # no map, no temporary file


def test_prefetched_yields_every_item_in_order() -> None:
    assert list(prefetched(lambda k: k * k, 7)) == [0, 1, 4, 9, 16, 25, 36]
    assert list(prefetched(lambda k: k, 0)) == []


def test_a_loading_error_is_raised_after_the_items_before_it() -> None:
    def load(k: int) -> int:
        if k == 3:
            raise InvalidInputError("frame 3 is broken")
        return k

    got = []
    with pytest.raises(InvalidInputError, match="frame 3"):
        for item in prefetched(load, 6):
            got.append(item)
    assert got == [0, 1, 2]


def test_leaving_the_loop_early_stops_the_reading_thread() -> None:
    loaded = []
    before = threading.active_count()
    items = prefetched(loaded.append, 1000, depth=2)
    for k, _ in enumerate(items):
        if k == 4:
            break
    items.close()
    assert threading.active_count() == before  # the thread was joined
    assert 5 <= len(loaded) <= 5 + 2 + 1  # at most `depth` ready plus one in hand
