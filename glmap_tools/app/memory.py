"""Give freed memory back to the operating system after a session lets go of a lot of it.

glibc serves numpy's multi-megabyte arrays from its heap once a large block has been freed
(its mmap threshold rises to 32 MB), and a heap freed in the middle stays resident: a
server whose sessions dropped their maps and pending frames kept its peak size (issue 27
item 2: 5 GB after new_map). `trim()` asks glibc to return free pages (malloc_trim); it
is a no-op on other C libraries.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from collections.abc import Callable


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
