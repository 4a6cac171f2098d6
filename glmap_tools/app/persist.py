"""`glmap-mcp --map NAME`: one saved map, and its simulator episode, shared by processes.

Some MCP clients start a fresh server process for every tool call (LangChain's default
`get_tools()`, the Inspector CLI). With `--map NAME` each process works on the saved map
`<maps_dir>/NAME.glmap` (made empty if absent): the default session is pinned to it, every
frame commits there, and the running simulator episode is kept in the same file as an
*episode record* (a JSON extra of the store, written in the frame's own transaction):
how the episode began (task, scene or benchmark id, size, step limit, seed, goal), the
actions taken, and the navigation memory. A new process replays the record (the env is
deterministic for a seed) and so continues exactly where the last one stopped.

Each tool call holds an exclusive lock on the map (an flock on `.NAME.glmap.lock` beside
it, released by the kernel if the process dies): a process that finds it held waits up to
`ServerConfig.map_wait_s` and then fails the call with an error saying so. At the start
of a call the map and the episode are re-read if another process changed them.
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import sqlite3
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from glmap_tools.app.episode_record import episode_record, restore_episode
from glmap_tools.app.session import MAP_SUFFIX, LiveMap, Session, check_map_name
from glmap_tools.errors import GLMapError, StoreError

if TYPE_CHECKING:
    from glmap_tools.app.config import ServerConfig
    from glmap_tools.language.embed import Embedder
    from glmap_tools.language.text_merger import TextMerger
    from glmap_tools.map import MapConfig

# Imports inside functions stay there: cv2, gaussians, language.embed, scipy load on first use:
# build_server stays light (test_server_startup): the server loads them in the background or on
# first use; the tools load before these do, in the server and the in-process toolset alike.

log = logging.getLogger(__name__)

# This module is imported before the handshake: the map, store and simulator modules
# (numpy, scipy, numba) are imported inside the functions that need them.
MAP_FORMAT = "glmap-tools map"  # glmap_tools.map.store.FORMAT (a test holds them equal)

EPISODE = "sim_episode"  # the store extra holding the episode record
POLL_S = 0.05


class MapLock:
    """An exclusive flock on `<maps_dir>/.<name>.glmap.lock`, waiting at most `wait_s`."""

    def __init__(self, path: Path, name: str, wait_s: float) -> None:
        self.path = path
        self.name = name
        self.wait_s = wait_s
        self._fd: int | None = None

    def acquire(self) -> None:
        """Take the lock, polling until `wait_s` has passed.

        Raises:
            StoreError: another process held it all that time (the message names its pid).
        """

        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o600)
        deadline = time.monotonic() + self.wait_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    holder = _read_pid(fd)
                    os.close(fd)
                    who = f"process {holder}" if holder else "another process"
                    raise StoreError(
                        f"map {self.name!r} is in use by {who} (another glmap-mcp --map "
                        f"{self.name}) and stayed locked for {self.wait_s:g} s; try the call "
                        "again when it is done, or start this server with a longer --map-wait."
                    ) from None
                time.sleep(POLL_S)
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor drops the flock
            self._fd = None


def _read_pid(fd: int) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def check_saved_map(path: Path, name: str, config: MapConfig, embedder: str) -> None:
    """Refuse, cheaply (meta table only), a map file `--map` could not open as configured.

    Args:
        path: the map file (nothing is checked if it does not exist).
        name: the --map name, for messages.
        config: the map settings of this server.
        embedder: the --embedder choice ('minilm' or 'hashing').

    Run at launch, so a wrong --map fails before the handshake rather than on a tool
    call; the full check of every row comes when the map is opened.

    Raises:
        StoreError: not a GLMap store, or built with another embedder or map settings.
    """
    if not path.exists():
        return
    if not path.is_file():
        raise StoreError(f"--map {name!r}: {path.name} is not a file; choose another name.")
    try:
        conn = sqlite3.connect(f"{path.absolute().as_uri()}?mode=ro", uri=True)
        try:
            meta = dict(conn.execute("SELECT key, value FROM meta").fetchall())
        finally:
            conn.close()
    except (sqlite3.Error, ValueError) as exc:
        raise StoreError(
            f"--map {name!r}: {path.name} is not a GLMap store ({exc}); it was left as it is. "
            "Move it away or choose another --map name."
        ) from None
    if meta.get("format") != MAP_FORMAT:
        raise StoreError(
            f"--map {name!r}: {path.name} is an SQLite file but not a GLMap store; it was "
            "left as it is. Move it away or choose another --map name."
        )
    built = embedder_option(meta.get("embedder"))
    if built is not None and built != embedder:
        raise StoreError(
            f"--map {name!r} was built with --embedder {built} but this server uses "
            f"--embedder {embedder} (their embeddings differ); start it with --embedder "
            f"{built}, or choose another --map name."
        )
    try:
        saved = json.loads(meta.get("config", "{}"))
    except json.JSONDecodeError:
        saved = None
    if not isinstance(saved, dict):
        raise StoreError(
            f"--map {name!r}: {path.name} has an unreadable config; it was left as it is. "
            "Move it away or choose another --map name."
        )
    mismatch = config_mismatch(saved, config)
    if mismatch:
        raise StoreError(f"--map {name!r} {mismatch}")


def embedder_option(stored: str | None) -> str | None:
    """The --embedder choice that makes embeddings named `stored` (as a store records them)."""
    if stored is None:
        return None
    if stored.startswith("hashing-"):
        return "hashing"
    return "minilm" if stored == "all-MiniLM-L6-v2" else stored


def config_mismatch(saved: dict[str, Any], config: MapConfig) -> str:
    """'' when the saved map settings equal `config`, else what differs and the fix."""
    wanted = config.to_dict()
    differ = sorted(k for k in set(saved) | set(wanted) if saved.get(k) != wanted.get(k))
    if not differ:
        return ""
    shown = ", ".join(f"{k}={saved.get(k)!r} (this server: {wanted.get(k)!r})" for k in differ)
    return (
        f"was built with other map settings: {shown}. Start the server with the same settings "
        "(e.g. --voxel-size) as the process that made it, or choose another --map name."
    )


class Sessions(Protocol):
    """What a PinnedMap uses of the process's sessions (glmap_tools.app.state.SessionRegistry)."""

    config: ServerConfig
    embedder: Embedder
    maps_dir: Path

    def map_path(self, name: str) -> Path: ...
    def default_session(self) -> Session: ...
    def new_map(self, session: Session, name: str | None) -> LiveMap: ...
    def load_map(self, session: Session, name: str) -> LiveMap: ...
    def _merger(self) -> TextMerger: ...


class PinnedMap:
    """The map and episode `--map NAME` pins the default session to (one per process).

    `enter()`/`exit()` bracket every tool call (re-entrant across the calls of one
    process): the first enter takes the lock and brings the map and the episode up to
    date with the file; the last exit writes the episode record and lets the lock go.

    Args:
        registry: the process's sessions and maps.
        name: the map name (checked: a bare name).
    """

    def __init__(self, registry: Sessions, name: str) -> None:
        self.registry = registry
        self.name = check_map_name(name)
        self.path = registry.map_path(self.name)
        self.lock = MapLock(
            self.path.parent / f".{self.name}{MAP_SUFFIX}.lock",
            self.name,
            registry.config.map_wait_s,
        )
        self.live: LiveMap | None = None
        self.record: str | None = None  # the episode record as last read or written
        self._mutex = threading.Lock()
        self._depth = 0

    # ------------------------------------------------------------------ call scope
    def enter(self) -> None:
        """Start of a tool call: lock the map and bring this process up to date.

        Raises:
            StoreError: the map stayed locked, or its file cannot be opened as configured.
        """
        with self._mutex:
            if self._depth == 0:
                self.registry.maps_dir.mkdir(parents=True, exist_ok=True)
                self.lock.acquire()
                try:
                    self._sync(self.registry.default_session())
                except BaseException:
                    self.lock.release()
                    raise
            self._depth += 1

    def exit(self) -> None:
        """End of a tool call: write the episode record if it changed; unlock at the last."""
        with self._mutex:
            self._depth -= 1
            if self._depth > 0:
                return
            try:
                self._write_record()
            finally:
                self.lock.release()

    def flush(self) -> None:
        """Write the episode record if it changed since a call's end (at the server's end).

        A safety net: each call already writes it on `exit` (the MCP server's `guard_calls`).
        """
        with self._mutex:
            if self._depth or self.live is None:
                return
            session = self.registry.default_session()
            if not self.holds(session) or episode_record(session) in (None, self.record):
                return  # nothing to write: do not wait for the lock on the way out
            try:
                self.lock.acquire()
            except StoreError as exc:
                log.warning("glmap-mcp: the episode's last changes were not kept: %s", exc)
                return
            try:
                self._write_record()
            finally:
                self.lock.release()

    def _write_record(self) -> None:
        session = self.registry.default_session()
        if not self.holds(session):
            return
        text = episode_record(session)
        if text is not None and text != self.record:
            assert self.live is not None and self.live.glmap.store is not None
            with self.live.lock:
                self.live.glmap.store.write_extra(EPISODE, text)
            self.record = text

    def ensure(self, session: Session) -> None:
        """Make sure `session` (the default one) is on the map; for calls outside a scope."""
        if self._depth == 0 or self.live is None:
            self.enter()
            self.exit()

    def holds(self, session: Session) -> bool:
        """Whether `session` works on the pinned map now (new_map/load_map may switch it)."""
        return self.live is not None and session.live is self.live

    # ------------------------------------------------------------------ syncing
    def _sync(self, session: Session) -> None:
        registry = self.registry
        if self.live is None:
            if self.path.exists():
                check_saved_map(
                    self.path, self.name, registry.config.map_config, registry.config.embedder
                )
                live = registry.load_map(session, self.name)
            else:
                live = registry.new_map(session, self.name)
            self.live = live
            session.recorder = self
        elif not self.holds(session):
            return  # the session moved to another map: leave both alone
        else:
            store = self.live.glmap.store
            if store is None or not store.changed_elsewhere():
                return
            if self.path.exists():
                self._reload()
            else:  # removed since: a fresh map and no episode, as a new process would start
                log.info("map %r was removed: starting it anew", self.name)
                self.clear()
                session.end_episode()
        store = self.live.glmap.store
        assert store is not None
        store.mark_seen()
        text = store.read_extra(EPISODE)
        if text is not None and text != self.record:
            log.info("continuing the simulator episode of map %r", self.name)
            try:
                restore_episode(session, text, registry.config, registry.embedder)
            except GLMapError as exc:  # the map is fine; the episode must start anew
                session.end_episode()
                log.warning("glmap-mcp: %s", exc)
        self.record = text

    def _reload(self) -> None:
        """Read the map file again (another process committed to it or replaced it)."""
        from glmap_tools.map import GLMap

        assert self.live is not None
        registry = self.registry
        fresh = GLMap.open(self.path, embedder=registry.embedder, text_merger=registry._merger())
        mismatch = config_mismatch(fresh.config.to_dict(), registry.config.map_config)
        if mismatch:
            fresh.close()
            raise StoreError(f"--map {self.name!r} {mismatch}")
        with self.live.lock:
            old, self.live.glmap = self.live.glmap, fresh
            old.close()

    def clear(self) -> None:
        """Empty the pinned map (a fresh map in the same file), as a new scratch map would be."""
        from glmap_tools.map import GLMap
        from glmap_tools.map.store import MapStore

        assert self.live is not None
        registry = self.registry
        with self.live.lock:
            old = self.live.glmap
            empty = GLMap(old.config, embedder=registry.embedder, text_merger=registry._merger())
            empty.store = MapStore.create_from(self.path, empty, overwrite=True)
            self.live.glmap = empty
            old.close()
        self.record = None

    # ------------------------------------------------------------------ frames
    def stage(self, session: Session) -> str | None:
        """Stage the episode record into the next frame's transaction; return its text."""
        if not self.holds(session) or self.live is None or self.live.glmap.store is None:
            return None
        text = episode_record(session)
        if text is not None:
            self.live.glmap.store.stage_extra(EPISODE, text)
        return text

    def committed(self, text: str | None) -> None:
        """The frame carrying the staged record `text` was committed."""
        if text is not None:
            self.record = text
