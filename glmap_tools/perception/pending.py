"""Frames whose segments wait for names (issue 11 item 3), bounded in count and age.

`observe_frame` without annotations integrates a frame's geometry and occupancy at once and
parks its segments here under a short token ("f3"); `label_segments` takes them back, names
them and fuses the labelled ones. A pending frame expires after `max_age_s`, when more than
`max_frames` wait (oldest first), or when its session's map is replaced.
"""

from __future__ import annotations

import itertools
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import UnknownIdError
from glmap_tools.geometry.frame import RGBDFrame

if TYPE_CHECKING:
    from glmap_tools.perception.geometric import Segment

MAX_PENDING_FRAMES = 8
MAX_PENDING_AGE_S = 900.0


@dataclass(frozen=True)
class PendingFrame:
    """A frame already integrated as geometry, its segments still unnamed.

    Attributes:
        token: the id the agent names the frame by.
        frame: the posed RGB-D frame.
        segments: its segments (ids 1..K).
        frame_index: the map frame index it was integrated under.
        created: clock time it was parked (s).
        owner: weak reference to the map it belongs to.
    """

    token: str
    frame: RGBDFrame
    segments: tuple[Segment, ...]
    frame_index: int
    created: float
    owner: weakref.ref

    def masked_frame(self, mask: np.ndarray) -> RGBDFrame:
        """The frame with depth only on `mask` ([H, W] bool): the labelled objects' pass."""
        depth = np.where(mask, self.frame.depth, 0.0).astype(np.float32)
        return RGBDFrame(self.frame.rgb, depth, self.frame.intrinsics, self.frame.pose)


class PendingFrames:
    """Pending frames of every session, oldest first, thread-safe."""

    def __init__(
        self,
        max_frames: int = MAX_PENDING_FRAMES,
        max_age_s: float = MAX_PENDING_AGE_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.max_frames, self.max_age_s, self.clock = max_frames, max_age_s, clock
        self._frames: OrderedDict[tuple[str, str], PendingFrame] = OrderedDict()
        self._expired: OrderedDict[tuple[str, str], str] = OrderedDict()  # why, for messages
        self._counter = itertools.count(1)
        self._lock = threading.Lock()

    def add(
        self,
        session: str,
        owner: object,
        frame: RGBDFrame,
        segments: list[Segment],
        frame_index: int,
    ) -> PendingFrame:
        """Park a frame's segments for `session`; returns the pending frame (its token)."""
        with self._lock:
            self._expire_locked()
            token = f"f{next(self._counter)}"
            pending = PendingFrame(
                token, frame, tuple(segments), frame_index, self.clock(), weakref.ref(owner)
            )
            self._frames[(session, token)] = pending
            mine = [k for k in self._frames if k[0] == session]
            for key in mine[: max(0, len(mine) - self.max_frames)]:
                self._drop_locked(key, f"more than {self.max_frames} frames were waiting")
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
