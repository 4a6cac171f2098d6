"""A client session's working state and the names of saved maps.

`Session` is what one client works in: its map (a `LiveMap`, possibly shared with other
sessions through a saved file), its simulator episode and that episode's navigation
state. Which session a call belongs to is glmap_tools.app.state's job.
"""

from __future__ import annotations

import os
import re
import stat
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from glmap_tools.errors import InvalidInputError

if TYPE_CHECKING:
    from glmap_tools.app.nav_session import NavSession
    from glmap_tools.app.simulator import SimEpisode
    from glmap_tools.map import GLMap

MAP_SUFFIX = ".glmap"
MAP_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
DEFAULT_HANDLE = "default"


@dataclass
class LiveMap:
    """A map in memory, possibly backed by a store file, with the lock that guards it.

    Attributes:
        glmap: the map.
        name: saved map name (its file is `<maps_dir>/<name>.glmap`), None for scratch maps.
        lock: held by every read and write of `glmap`.
        users: sessions currently working on it.
    """

    glmap: GLMap
    name: str | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)
    users: int = 0


class EpisodeRecorder(Protocol):
    """Where a session's simulator episode is recorded with each frame (`glmap-mcp --map`:
    glmap_tools.app.persist.PinnedMap)."""

    def stage(self, session: Session) -> str | None:
        """Stage the episode record into the next frame's transaction; return its text."""

    def committed(self, text: str | None) -> None:
        """The frame carrying the staged record `text` was committed."""


@dataclass
class Session:
    """One client's working state: its map, simulator episode and navigation state.

    Attributes:
        handle: the session's name (`default`, or an unguessable token).
        live: the map it works on.
        last_used: `time.monotonic()` of its latest call.
        sim: its simulator episode (sim_reset), or None.
        nav: the navigation state of that episode, or None.
        sim_lock: serialises its sim_reset and sim_step.
        recorder: records its episode with each frame (`--map`), or None.
    """

    handle: str
    live: LiveMap
    last_used: float = field(default_factory=time.monotonic)
    sim: SimEpisode | None = None
    nav: NavSession | None = None
    sim_lock: threading.RLock = field(default_factory=threading.RLock)
    recorder: EpisodeRecorder | None = None

    def close(self) -> None:
        """Close the simulator episode (the session ends)."""
        if self.sim is not None:
            self.sim.close()

    def end_episode(self) -> None:
        """Close the simulator episode and forget it and its navigation state."""
        self.close()
        self.sim = self.nav = None


def check_map_name(name: str, suffix: str = MAP_SUFFIX, what: str = "map name") -> str:
    """Return `name` (less `suffix`) if it is a bare file name, else raise naming the fix.

    Args:
        name: the name a client gave.
        suffix: the file suffix the name may end with (stripped).
        what: what the name is, for the error message ("map name", "export name").

    Raises:
        InvalidInputError: a path separator, '..', a suffix or other characters.
    """
    if not isinstance(name, str):
        raise InvalidInputError(f"{what} must be a string, got {type(name).__name__}.")
    if "/" in name or "\\" in name or ".." in name or name.startswith("~"):
        raise InvalidInputError(
            f"{what} {name!r} contains a path; give a bare name such as 'kitchen' "
            "(files are kept in the server's maps folder, which nothing outside of is touched)."
        )
    stem = name[: -len(suffix)] if name.endswith(suffix) else name
    if not MAP_NAME.fullmatch(stem):
        raise InvalidInputError(
            f"{what} {name!r} is not allowed; use 1-64 letters, digits, '-' or '_', "
            "starting with a letter or digit, e.g. 'flat-3'."
        )
    return stem


def saved_maps(folder: Path) -> dict[str, os.stat_result]:
    """{name: lstat} of the regular `.glmap` files directly in `folder`.

    Symlinks are left out (they could point anywhere, and stat would report the target's
    size and time), as are folders and hidden files.
    """
    out: dict[str, os.stat_result] = {}
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return out
    for entry in entries:
        name = entry.name
        if not name.endswith(MAP_SUFFIX) or name.startswith(".") or entry.is_symlink():
            continue
        try:
            info = entry.stat(follow_symlinks=False)
        except OSError:
            continue  # removed since listed
        if stat.S_ISREG(info.st_mode) and MAP_NAME.fullmatch(name[: -len(MAP_SUFFIX)]):
            out[name[: -len(MAP_SUFFIX)]] = info
    return out


@contextmanager
def locked(session: Session) -> Iterator[GLMap]:
    """Hold the lock of the session's current map and yield the map."""
    live = session.live
    with live.lock:
        yield live.glmap
