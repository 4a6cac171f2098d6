"""Give freed memory back to the operating system after a session lets go of a lot of it.

glibc serves numpy's multi-megabyte arrays from its heap once a large block has been freed
(its mmap threshold rises to 32 MB), and a heap freed in the middle stays resident: a
server whose sessions dropped their maps and pending frames kept its peak size (issue 27
item 2: 5 GB after new_map). `trim()` asks glibc to return free pages (malloc_trim); it
is a no-op on other C libraries.

`FrameWork` bounds the memory of frames being decoded and worked on at once (issue 41 item
3): without it, 8 sessions sending 2048 x 2048 frames with 3 / 4 / 8 calls in flight took
985 / 1084 / 1743 MiB above start, past the documented 768.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import traceback
import weakref
from collections import deque
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

import anyio


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        fn = libc.malloc_trim
    except (OSError, AttributeError):  # not glibc
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn  # type: ignore[no-any-return]


def trim() -> bool:
    """Return the C heap's free pages to the system; whether anything could be returned."""
    fn = _malloc_trim()
    return bool(fn(0)) if fn is not None else False


# ------------------------------------------------------------------ frames in flight
MIB = 1 << 20
# Working memory of one observe_frame call beyond the frame it may leave pending: the decoded
# images, the depth in metres, the segmentation's and the Gaussian fit's arrays. Measured
# with `python -m glmap_tools.bench pending --sessions 1 --frames 1`: 41 MiB at 1024^2
# (39 B/px), 188 MiB at 2048^2 (45 B/px).
WORK_BYTES_PER_PIXEL = 48
MAX_FRAME_WORK_BYTES = 256 * MIB  # frames decoded and worked on at once, per server


def frame_work_bytes(width: int, height: int) -> int:
    """Working memory one observe_frame call of a width x height frame takes (estimate)."""
    return WORK_BYTES_PER_PIXEL * max(0, width) * max(0, height)


class FrameWork:
    """The frames a server decodes and works on at once, bounded in bytes.

    A call takes `frame_work_bytes` of its frame before decoding it and gives them back when
    it is done; a call that does not fit waits (in arrival order) for earlier ones to finish.
    A frame larger than the whole limit runs alone. So calls in flight hold at most
    `limit` bytes of frame work (or one frame), however many clients send frames at once.
    Used from one event loop (no lock needed).

    Args:
        limit: bytes of frame work in flight.
    """

    def __init__(self, limit: int = MAX_FRAME_WORK_BYTES) -> None:
        self.limit = limit
        self.used = 0  # bytes taken by the calls at work
        self.peak = 0  # the most bytes taken at once (for tests and benchmarks)
        self._queue: deque[tuple[int, anyio.Event]] = deque()

    def _fits(self, nbytes: int) -> bool:
        return self.used == 0 or self.used + nbytes <= self.limit

    def _take(self, nbytes: int) -> None:
        self.used += nbytes
        self.peak = max(self.peak, self.used)

    def _admit(self) -> None:
        while self._queue and self._fits(self._queue[0][0]):
            nbytes, event = self._queue.popleft()
            self._take(nbytes)
            event.set()

    @asynccontextmanager
    async def hold(self, nbytes: int) -> AsyncIterator[None]:
        """Take `nbytes` of frame work for the body (waiting for room), then give them back."""
        if self._queue or not self._fits(nbytes):
            entry = (nbytes, anyio.Event())
            self._queue.append(entry)
            try:
                await entry[1].wait()
            except BaseException:  # cancelled while waiting, or just after being admitted
                if entry in self._queue:
                    self._queue.remove(entry)
                else:
                    self.used -= nbytes
                self._admit()
                raise
        else:
            self._take(nbytes)
        try:
            yield
        except BaseException as exc:
            # A refused or failed call's arrays go now, not at the next garbage collection:
            # its traceback's frames (reference cycles with the exception) hold the decoded
            # frame. 2048^2 frames refused at the pending cap kept ~1 GiB until then.
            traceback.clear_frames(exc.__traceback__)
            raise
        finally:
            self.used -= nbytes
            self._admit()


_work: dict[int, FrameWork] = {}  # by id of the owner, while it lives


def frame_work(owner: object) -> FrameWork:
    """The FrameWork of `owner` (a server's state, unhashable), made on first use."""
    key = id(owner)
    work = _work.get(key)
    if work is None:
        work = _work[key] = FrameWork()
        weakref.finalize(owner, _work.pop, key, None)
    return work
