"""Read ahead: prepare the next items of a sequence on a thread while the caller uses this one.

`glmap build` fuses frame k while frame k+1 is read, decoded, perceived and its texts are
embedded. Image decoding (OpenCV), depth conversion and the embedder's matrix products
release the GIL, so on two cores the two stages overlap.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from typing import TypeVar, cast

T = TypeVar("T")

DEFAULT_DEPTH = 2  # items ready ahead: enough to hide a slow read, little memory (~5 MB each)
_PUT_POLL_S = 0.1  # how often a blocked producer looks whether the consumer has gone


def prefetched(load: Callable[[int], T], count: int, depth: int = DEFAULT_DEPTH) -> Iterator[T]:
    """Yield load(0), ..., load(count - 1) in order, each prepared on a thread ahead of use.

    At most `depth` items wait ready at any time. An exception raised by `load(k)` is raised
    here when item k would have been yielded (items before it are yielded first), and the
    thread stops. Closing the iterator early (break, an exception in the caller's loop)
    stops the thread and waits for it, so no load runs on after the caller returns.

    Args:
        load: prepares item k; called on one thread, in order.
        count: number of items.
        depth: items prepared ahead (>= 1).
    """
    if depth < 1:
        raise ValueError(f"depth={depth!r} must be >= 1.")
    ready: queue.Queue[tuple[bool, object]] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def produce() -> None:
        for k in range(count):
            if stop.is_set():
                return
            try:
                item: tuple[bool, object] = (True, load(k))
            except BaseException as exc:  # handed to the consumer, raised there
                item = (False, exc)
            while not stop.is_set():
                try:
                    ready.put(item, timeout=_PUT_POLL_S)
                    break
                except queue.Full:
                    continue
            if not item[0]:
                return

    thread = threading.Thread(target=produce, name="glmap-prefetch", daemon=True)
    thread.start()
    try:
        for _ in range(count):
            ok, value = ready.get()
            if not ok:
                assert isinstance(value, BaseException)
                raise value
            yield cast(T, value)
    finally:
        stop.set()
        thread.join()
