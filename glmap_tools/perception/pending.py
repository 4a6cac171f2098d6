"""Frames whose segments wait for names (issue 11 item 3), bounded in count, age and bytes.

`observe_frame` without annotations integrates a frame's geometry and occupancy at once and
parks its segments here under a short token ("f3"); `label_segments` takes them back, names
them and fuses the labelled ones. A pending frame expires after `max_age_s`, when more than
`max_frames` wait (oldest first), when its session's frames pass `max_session_bytes`
(oldest first), or when its session's map is replaced or the session ends (`forget`).

Memory (issue 27 item 2): a frame is kept as its RGB, its depth and one label image
(segment id per pixel, 1 byte) -- 8 bytes a pixel, ~34 MB for 2048 x 2048 -- instead of a
full-size bool mask per segment (64 of them took ~245 MB). All sessions together hold at
most `max_server_bytes`; a frame that would go past it is refused (`LimitError`), before
anything is integrated.
"""

from __future__ import annotations

import dataclasses
import itertools
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import LimitError, UnknownIdError
from glmap_tools.geometry.frame import RGBDFrame

if TYPE_CHECKING:
    from glmap_tools.perception.geometric import Segment

MIB = 1 << 20
MAX_PENDING_FRAMES = 8
MAX_PENDING_AGE_S = 900.0
MAX_SESSION_PENDING_BYTES = 128 * MIB  # ~3 frames of 2048 x 2048, 50 of 640 x 480
MAX_SERVER_PENDING_BYTES = 512 * MIB  # every session together
_NO_MASK = np.zeros((0, 0), dtype=bool)


def pending_bytes(height: int, width: int) -> int:
    """Bytes a pending H x W frame holds: RGB (3), depth (4) and its label image (1)."""
    return height * width * 8


@dataclass(frozen=True)
class PendingFrame:
    """A frame already integrated as geometry, its segments still unnamed.

    Attributes:
        token: the id the agent names the frame by.
        frame: the posed RGB-D frame.
        labels: [H, W] uint8 segment id of each pixel (0: none).
        infos: its segments (ids 1..K) without their masks and crops.
        frame_index: the map frame index it was integrated under.
        created: clock time it was parked (s).
        owner: weak reference to the map it belongs to.
    """

    token: str
    frame: RGBDFrame
    labels: np.ndarray  # [H, W] uint8
    infos: tuple[Segment, ...]
    frame_index: int
    created: float
    owner: weakref.ref

    @property
    def nbytes(self) -> int:
        return self.frame.rgb.nbytes + self.frame.depth.nbytes + self.labels.nbytes

    def segments(self, wanted: Sequence[int] | None = None) -> list[Segment]:
        """The segments with their [H, W] bool masks rebuilt from the label image.

        Args:
            wanted: ids whose masks are needed (None: all); the others get a read-only
                all-False mask that takes no memory.
        """
        keep = None if wanted is None else set(wanted)
        empty = np.broadcast_to(np.False_, self.labels.shape)
        return [
            dataclasses.replace(
                s, mask=self.labels == s.id if keep is None or s.id in keep else empty
            )
            for s in self.infos
        ]

    def masked_frame(self, mask: np.ndarray) -> RGBDFrame:
        """The frame with depth only on `mask` ([H, W] bool): the labelled objects' pass."""
        depth = np.where(mask, self.frame.depth, 0.0).astype(np.float32)
        return RGBDFrame(self.frame.rgb, depth, self.frame.intrinsics, self.frame.pose)


def label_image(shape: tuple[int, int], segments: Sequence[Segment]) -> np.ndarray:
    """[H, W] uint8 (uint16 past 255 segments) id of the segment on each pixel, 0 elsewhere.

    Segments of one frame are disjoint (segment_frame cuts one label image).
    """
    dtype = np.uint8 if max((s.id for s in segments), default=0) <= 255 else np.uint16
    labels = np.zeros(shape, dtype=dtype)
    for s in segments:
        labels[s.mask] = s.id
    return labels


class PendingFrames:
    """Pending frames of every session, oldest first, thread-safe.

    Args:
        max_frames: frames one session keeps (the oldest go first).
        max_age_s: seconds a frame is kept.
        clock: monotonic seconds (tests pass their own).
        max_session_bytes: bytes one session keeps (the oldest go first; one frame
            larger than this is refused); None: MAX_SESSION_PENDING_BYTES.
        max_server_bytes: bytes every session together keeps (a frame past it is refused);
            None: MAX_SERVER_PENDING_BYTES.
    """

    def __init__(
        self,
        max_frames: int = MAX_PENDING_FRAMES,
        max_age_s: float = MAX_PENDING_AGE_S,
        clock: Callable[[], float] = time.monotonic,
        max_session_bytes: int | None = None,
        max_server_bytes: int | None = None,
    ) -> None:
        self.max_frames, self.max_age_s, self.clock = max_frames, max_age_s, clock
        self.max_session_bytes = max_session_bytes or MAX_SESSION_PENDING_BYTES
        self.max_server_bytes = max_server_bytes or MAX_SERVER_PENDING_BYTES
        self._frames: OrderedDict[tuple[str, str], PendingFrame] = OrderedDict()
        self._expired: OrderedDict[tuple[str, str], str] = OrderedDict()  # why, for messages
        self._reserved: dict[int, int] = {}  # bytes promised to frames being integrated
        self._counter = itertools.count(1)
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ bytes
    def held(self, session: str | None = None) -> int:
        """Bytes the pending frames hold (of one session, or of all), reservations included."""
        with self._lock:
            return self._held_locked(session)

    def _held_locked(self, session: str | None) -> int:
        frames = sum(p.nbytes for k, p in self._frames.items() if session in (None, k[0]))
        return frames + (sum(self._reserved.values()) if session is None else 0)

    @contextmanager
    def room(self, session: str, nbytes: int) -> Iterator[None]:
        """Reserve `nbytes` for a frame of `session` while it is integrated and parked.

        Raises:
            LimitError: the frame alone is larger than a session may keep, or the server's
                pending frames would pass `max_server_bytes`; nothing is kept.
        """
        mib = MIB
        with self._lock:
            self._expire_locked()
            if nbytes > self.max_session_bytes:
                raise LimitError(
                    f"this frame would keep {nbytes / mib:.1f} MiB waiting for label_segments, "
                    f"more than a session may keep ({self.max_session_bytes / mib:.0f} MiB); "
                    "send a smaller image, or send annotations with observe_frame."
                )
            mine = self._held_locked(session)  # the oldest of these may go to make room
            total = self._held_locked(None) - mine + min(mine, self.max_session_bytes - nbytes)
            if total + nbytes > self.max_server_bytes:
                raise LimitError(
                    f"the server's frames waiting for label_segments hold "
                    f"{self._held_locked(None) / mib:.1f} MiB, and this one "
                    f"({nbytes / mib:.1f} MiB) would pass its cap of "
                    f"{self.max_server_bytes / mib:.0f} MiB; label or let go of pending frames "
                    "(label_segments, new_map), send annotations with observe_frame, or try "
                    f"again later (they expire after {self.max_age_s:.0f} s)."
                )
            key = next(self._counter)
            self._reserved[key] = nbytes
        try:
            yield
        finally:
            with self._lock:
                self._reserved.pop(key, None)

    # ------------------------------------------------------------------ frames
    def add(
        self,
        session: str,
        owner: object,
        frame: RGBDFrame,
        segments: list[Segment],
        frame_index: int,
    ) -> PendingFrame:
        """Park a frame's segments for `session`; returns the pending frame (its token).

        The session's oldest frames go while it keeps more than `max_frames` frames or
        `max_session_bytes` bytes.
        """
        labels = label_image(frame.depth.shape, segments)
        infos = tuple(dataclasses.replace(s, mask=_NO_MASK, crop=_NO_MASK) for s in segments)
        with self._lock:
            self._expire_locked()
            token = f"f{next(self._counter)}"
            pending = PendingFrame(
                token, frame, labels, infos, frame_index, self.clock(), weakref.ref(owner)
            )
            self._frames[(session, token)] = pending
            mine = [k for k in self._frames if k[0] == session]
            for key in mine[: max(0, len(mine) - self.max_frames)]:
                self._drop_locked(key, f"more than {self.max_frames} frames were waiting")
            mine = [k for k in self._frames if k[0] == session]
            while len(mine) > 1 and self._held_locked(session) > self.max_session_bytes:
                self._drop_locked(
                    mine.pop(0),
                    f"this session's waiting frames passed {self.max_session_bytes / MIB:.0f} MiB",
                )
            return pending

    def get(self, session: str, token: str, owner: object) -> PendingFrame:
        """The pending frame `token` of `session` for map `owner`.

        Raises:
            UnknownIdError: an unknown or expired token, or a map replaced since.
        """
        with self._lock:
            self._expire_locked()
            key = (session, token)
            pending = self._frames.get(key)
            if pending is not None and pending.owner() is not owner:
                self._drop_locked(key, "the session's map was replaced or closed since")
                pending = None
            if pending is None:
                waiting = [k[1] for k in self._frames if k[0] == session]
                why = self._expired.get(key)
                detail = f"it expired ({why})" if why else "no frame has that id"
                raise UnknownIdError(
                    f"frame {token!r} has no pending segments: {detail}. Pending frames: "
                    f"{waiting or 'none'}; observe the frame again (without annotations) "
                    "for new segments."
                )
            return pending

    def remove(self, session: str, token: str) -> None:
        """Forget a labelled frame."""
        with self._lock:
            self._frames.pop((session, token), None)
            self._expired[(session, token)] = "its segments were already labelled"

    def forget(self, session: str) -> None:
        """Let go of every frame of `session`: its map was replaced, or it ended."""
        with self._lock:
            for key in [k for k in self._frames if k[0] == session]:
                self._drop_locked(key, "the session's map was replaced or closed since")

    def tokens(self, session: str) -> list[str]:
        """The session's pending frame ids, oldest first."""
        with self._lock:
            self._expire_locked()
            return [k[1] for k in self._frames if k[0] == session]

    def _drop_locked(self, key: tuple[str, str], why: str) -> None:
        self._frames.pop(key, None)
        self._expired[key] = why
        while len(self._expired) > 256:  # remember a few reasons, not all of them
            self._expired.popitem(last=False)

    def _expire_locked(self) -> None:
        now = self.clock()
        for key, pending in list(self._frames.items()):
            if now - pending.created > self.max_age_s:
                self._drop_locked(key, f"pending frames keep {self.max_age_s:.0f} s")
            elif pending.owner() is None:
                self._drop_locked(key, "the session's map was replaced or closed since")
