"""Pending frames expire by count, age and map; the contact sheet shows every segment."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools import synthetic as sy
from glmap_tools.errors import UnknownIdError
from glmap_tools.perception.geometric import segment_frame
from glmap_tools.perception.pending import PendingFrames
from glmap_tools.perception.sheet import TILE, segment_color, segment_sheet


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Owner:
    """Stands for a map: pending frames hold it by weak reference."""


@pytest.fixture(scope="module")
def frame_and_segments():
    boxes = sy.floor() + sy.chair(0.0, 0.5, object_id=1) + sy.table(1.3, 0.8, 2)
    frame, _ = sy.view(boxes, (0.3, -2.0, 1.4), (0.3, 0.8, 0.4))
    return frame, segment_frame(frame)


def test_the_oldest_frames_expire_beyond_the_count_limit(frame_and_segments):
    frame, segments = frame_and_segments
    store, owner = PendingFrames(max_frames=2), Owner()
    tokens = [store.add("s", owner, frame, segments, i).token for i in range(3)]
    assert store.tokens("s") == tokens[1:]
    with pytest.raises(UnknownIdError, match="more than 2 frames"):
        store.get("s", tokens[0], owner)
    assert store.get("s", tokens[2], owner).frame_index == 2


def test_frames_expire_with_age_and_sessions_do_not_see_each_other(frame_and_segments):
    frame, segments = frame_and_segments
    clock, owner = Clock(), Owner()
    store = PendingFrames(max_age_s=60.0, clock=clock)
    token = store.add("a", owner, frame, segments, 0).token
    with pytest.raises(UnknownIdError, match="no frame has that id"):
        store.get("b", token, owner)
    clock.now = 59.0
    assert store.get("a", token, owner).token == token
    clock.now = 61.0
    with pytest.raises(UnknownIdError, match="keep 60 s"):
        store.get("a", token, owner)


def test_a_frame_of_another_map_is_expired(frame_and_segments):
    frame, segments = frame_and_segments
    store = PendingFrames()
    owner = Owner()
    token = store.add("s", owner, frame, segments, 0).token
    with pytest.raises(UnknownIdError, match="replaced or closed"):
        store.get("s", token, Owner())
    with pytest.raises(UnknownIdError, match="replaced or closed"):  # and stays expired
        store.get("s", token, owner)


def test_the_masked_frame_keeps_depth_only_on_the_mask(frame_and_segments):
    frame, segments = frame_and_segments
    pending = PendingFrames().add("s", Owner(), frame, segments, 0)
    masked = pending.masked_frame(segments[0].mask)
    assert np.all(masked.depth[~segments[0].mask] == 0)
    np.testing.assert_array_equal(masked.depth[segments[0].mask], frame.depth[segments[0].mask])


def test_the_contact_sheet_has_a_tile_per_segment_in_its_colour(frame_and_segments):
    frame, segments = frame_and_segments
    sheet = segment_sheet(frame.rgb, segments)
    assert sheet.dtype == np.uint8 and sheet.shape[2] == 3
    rows = (len(segments) + 3) // 4
    overview_height = sheet.shape[0] - rows * TILE
    assert overview_height > 0
    for seg in segments:  # each outline colour shows in the overview
        assert np.all(sheet[:overview_height] == segment_color(seg.id), axis=-1).any()


def test_a_pending_frame_keeps_one_label_image_not_a_mask_per_segment(frame_and_segments):
    # Issue 27 item 2: 64 full-size bool masks made a 2048 x 2048 pending frame ~245 MB.
    import gc
    import tracemalloc

    frame = frame_and_segments[0]
    height, width = frame.depth.shape
    store, owner = PendingFrames(), Owner()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        segments = segment_frame(frame)
        assert len(segments) >= 3
        token = store.add("s", owner, frame, segments, 0).token
        del segments
        gc.collect()
        kept = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert kept < height * width + 64 * 1024, f"{kept} bytes kept for a {width}x{height} frame"
    assert store.held("s") == height * width * 8  # RGB, depth, label image
    pending = store.get("s", token, owner)
    again = segment_frame(frame)
    for seg, rebuilt in zip(again, pending.segments(), strict=True):
        np.testing.assert_array_equal(rebuilt.mask, seg.mask)
        assert (rebuilt.id, rebuilt.pixels, rebuilt.box) == (seg.id, seg.pixels, seg.box)


def test_a_session_past_its_byte_cap_lets_its_oldest_frames_go(frame_and_segments):
    frame, segments = frame_and_segments
    one = frame.depth.size * 8
    store, owner = PendingFrames(max_session_bytes=2 * one, max_server_bytes=10 * one), Owner()
    tokens = [store.add("s", owner, frame, segments, i).token for i in range(3)]
    assert store.tokens("s") == tokens[1:] and store.held("s") == 2 * one
    with pytest.raises(UnknownIdError, match="passed"):
        store.get("s", tokens[0], owner)


def test_a_frame_past_the_server_cap_is_refused_naming_the_cap(frame_and_segments):
    from glmap_tools.errors import LimitError

    frame, segments = frame_and_segments
    one = frame.depth.size * 8
    store, owner = PendingFrames(max_session_bytes=2 * one, max_server_bytes=4 * one), Owner()
    for session in ("a", "b"):
        for i in range(2):
            with store.room(session, one):
                store.add(session, owner, frame, segments, i)
    with (
        pytest.raises(LimitError, match=r"cap of \d+ MiB.*label_segments, new_map"),
        store.room("c", one),
    ):
        raise AssertionError("no room should have been given")
    assert store.held() == 4 * one  # b's and a's frames, not c's
    store.forget("a")
    with store.room("c", one):  # a's frames are gone: room again
        pass
    with store.room("b", one):  # b makes room by letting its own oldest frame go
        pass
    with pytest.raises(LimitError, match="more than a session may keep"), store.room("c", 3 * one):
        pass


def test_a_new_map_or_an_ended_session_lets_go_of_its_pending_frames(frame_and_segments, tmp_path):
    from glmap_tools.app.config import ServerConfig
    from glmap_tools.app.state import SessionRegistry
    from glmap_tools.language.embed import HashingEmbedder

    frame, segments = frame_and_segments
    registry = SessionRegistry(
        ServerConfig(maps_dir=tmp_path, embedder="hashing", warm_up=False), HashingEmbedder()
    )
    store = PendingFrames()
    registry.on_drop.append(store.forget)
    first, second = registry.start_session(), registry.start_session()
    for session in (first, second):
        store.add(session.handle, session.live.glmap, frame, segments, 0)
    registry.new_map(first, None)
    assert store.held(first.handle) == 0 and store.held(second.handle) > 0
    registry.close()
    assert store.held() == 0


def test_a_new_pinned_map_lets_go_of_the_frames_that_waited_for_it(frame_and_segments, tmp_path):
    from glmap_tools.app.config import ServerConfig
    from glmap_tools.app.state import SessionRegistry
    from glmap_tools.language.embed import HashingEmbedder

    frame, segments = frame_and_segments
    config = ServerConfig(maps_dir=tmp_path, embedder="hashing", warm_up=False, map_name="ep")
    registry = SessionRegistry(config, HashingEmbedder())
    store = PendingFrames()
    registry.on_drop.append(store.forget)
    pinned = registry.resolve(None, None)  # --map: the default session, on the saved map
    store.add(pinned.handle, pinned.live.glmap, frame, segments, 0)
    registry.new_map(pinned, None)  # starts the saved map anew, in place
    assert store.held(pinned.handle) == 0
    registry.close()
