"""Per-session map state: which map each client session works on, and who shares a saved map.

A *session* is what one client works in. Its key comes from the transport:

- an explicit `session` handle a tool was given (returned by new_map/load_map; this is how
  clients keep apart on the stateless 2026-07-28 protocol, which has no sessions);
- the `Mcp-Session-Id` header of a stateful streamable-HTTP connection;
- otherwise the server's *default* session (stdio and in-memory serve one client each).

With `glmap-mcp --map NAME` the default session is pinned to the saved map NAME, shared
with other processes through its file (glmap_tools.app.persist), and every call that
names no session works in it, whatever its connection. `session="default"` always names
the default session.

Each session starts on its own in-memory scratch map. A saved (named) map is one `LiveMap`
shared by every session that opened it, behind one lock, so concurrent sessions stay
consistent: there is one map in memory and one store file, never two diverging copies.
"""

from __future__ import annotations

import os
import secrets
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from glmap_tools.app.config import ServerConfig
from glmap_tools.app.memory import trim
from glmap_tools.app.persist import PinnedMap
from glmap_tools.app.session import (
    DEFAULT_HANDLE,
    MAP_SUFFIX,
    LiveMap,
    Session,
    check_map_name,
    saved_maps,
)
from glmap_tools.errors import (
    GLMapError,
    InvalidInputError,
    StoreError,
    UnknownIdError,
    did_you_mean,
)
from glmap_tools.language.backends import make_text_merger
from glmap_tools.map.store_file import make_folder

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.language.text_merger import TextMerger

# Imports inside functions stay there: cv2, gaussians, language.embed, scipy load on first use:
# build_server stays light (test_server_startup): the server loads them in the background or on
# first use; the tools load before these do, in the server and the in-process toolset alike.

DROPPED_KEPT = 4096  # dropped session keys remembered, to tell their clients


@contextmanager
def paths_hidden(folder: Path) -> Iterator[None]:
    """Re-raise a GLMapError with the maps folder's absolute path cut from its message."""
    try:
        yield
    except GLMapError as exc:
        text = str(exc)
        shown = text.replace(str(folder) + os.sep, "").replace(str(folder), "<maps folder>")
        if shown == text:
            raise
        hidden = type(exc).__new__(type(exc))
        hidden.args = (shown,)
        raise hidden from None


class SessionRegistry:
    """All sessions and open maps of one server process (thread-safe).

    Args:
        config: the server settings (maps folder, session limit, map settings).
        embedder: the text embedder every map uses.
    """

    def __init__(self, config: ServerConfig, embedder: Embedder) -> None:
        self.config = config
        self.embedder = embedder
        self.maps_dir = config.maps_dir.resolve()
        self._lock = threading.RLock()
        self._sessions: dict[str, Session] = {}
        self._by_transport: dict[str, str] = {}
        self._named: dict[str, LiveMap] = {}
        self._dropped: OrderedDict[str, float] = OrderedDict()  # handles and transport ids
        self.pin: PinnedMap | None = None  # the saved map of --map, if given
        # Called with a session's handle when its map is replaced or the session ends (what
        # the server keeps for it beside the map, e.g. pending frames, can go).
        self.on_drop: list[Callable[[str], None]] = []
        if config.map_name is not None:
            self.pin = PinnedMap(self, config.map_name)
        # The default session's map is made on first use: building a GLMap imports the
        # fusion code (scipy, numba), which the server's handshake must not wait for.

    # ------------------------------------------------------------------ maps
    def _merger(self) -> TextMerger:
        """The text merger of a map, as the settings ask (extractive unless told)."""

        return make_text_merger(self.config.llm, self.embedder)

    def _scratch(self) -> LiveMap:
        from glmap_tools.map import GLMap  # loads fusion (scipy, numba): not at import

        live = LiveMap(
            GLMap(self.config.map_config, embedder=self.embedder, text_merger=self._merger())
        )
        live.users = 1
        return live

    def map_path(self, name: str) -> Path:
        """`<maps_dir>/<name>.glmap`, refusing anything that would leave the maps folder."""
        stem = check_map_name(name)
        path = (self.maps_dir / f"{stem}{MAP_SUFFIX}").resolve()
        if path.parent != self.maps_dir:
            raise InvalidInputError(
                f"map name {name!r} resolves outside the maps folder; give a bare name."
            )
        return path

    def saved_names(self) -> list[str]:
        """Names of the map files in the maps folder, sorted (no symlinks, no folders)."""
        return sorted(saved_maps(self.maps_dir))

    def open_names(self) -> set[str]:
        with self._lock:
            return set(self._named)

    def _release(self, live: LiveMap) -> None:
        """One session stops using `live`; the last one out closes its store."""
        live.users -= 1
        if live.users > 0:
            return
        if live.name is not None and self._named.get(live.name) is live:
            del self._named[live.name]
        with live.lock:
            live.glmap.close()

    def _switch(self, session: Session, live: LiveMap) -> None:
        old = session.live
        session.live = live
        if old is not live:
            self._dropped_by(session)
            self._release(old)
            trim()  # the old map and what the session kept beside it, back to the system

    def _dropped_by(self, session: Session) -> None:
        for forget in self.on_drop:
            forget(session.handle)

    def new_map(self, session: Session, name: str | None) -> LiveMap:
        """Give `session` a fresh empty map: scratch, or a new store file `name`.

        Raises:
            InvalidInputError: a bad name.
            StoreError: a map of that name already exists.
        """
        with self._lock:
            if name is None:
                if self.pin is not None and self.pin.holds(session):
                    self.pin.clear()  # --map: the pinned map itself starts anew
                    self._dropped_by(session)  # with it, the frames that waited for it
                    return session.live
                self._switch(session, self._scratch())
                return session.live
            path = self.map_path(name)
            stem = path.name[: -len(MAP_SUFFIX)]
            if path.exists() or stem in self._named:
                raise StoreError(
                    f"a map named {stem!r} already exists; open it with load_map, or choose "
                    "another name."
                )
            from glmap_tools.map import GLMap

            make_folder(self.maps_dir)

            with paths_hidden(self.maps_dir):
                glmap = GLMap.open(
                    path,
                    self.config.map_config,
                    embedder=self.embedder,
                    text_merger=self._merger(),
                )
            live = LiveMap(glmap, stem, users=1)
            self._named[stem] = live
            self._switch(session, live)
            return live

    def load_map(self, session: Session, name: str) -> LiveMap:
        """Attach `session` to the saved map `name` (shared if another session has it open).

        A map open here that another process has written to since is read again.

        Raises:
            InvalidInputError: a bad name.
            UnknownIdError: no such map; the message suggests the closest name.
            StoreError: the file is not a map, or was built with another embedder.
        """
        with self._lock:
            path = self.map_path(name)
            stem = path.name[: -len(MAP_SUFFIX)]
            live = self._named.get(stem)
            store = live.glmap.store if live is not None else None
            pinned = self.pin is not None and self.pin.live is live
            if live is not None and store is not None and not pinned and store.changed_elsewhere():
                from glmap_tools.map import GLMap  # another process wrote to it: read it again

                with paths_hidden(self.maps_dir):
                    fresh = GLMap.open(path, embedder=self.embedder, text_merger=self._merger())
                with live.lock:
                    old, live.glmap = live.glmap, fresh
                    old.close()
            if live is None:
                if not path.is_file():
                    names = self.saved_names()
                    listing = f" Saved maps: {names}." if names else " No map is saved yet."
                    raise UnknownIdError(
                        f"no saved map named {stem!r}.{did_you_mean(stem, names)}{listing}"
                    )
                from glmap_tools.map import GLMap

                with paths_hidden(self.maps_dir):
                    glmap = GLMap.open(path, embedder=self.embedder, text_merger=self._merger())
                live = LiveMap(glmap, stem)
                self._named[stem] = live
            if session.live is not live:
                live.users += 1
                self._switch(session, live)
            return live

    def save_map(self, session: Session, name: str, overwrite: bool) -> tuple[LiveMap, bool]:
        """Write `session`'s map to `name` (atomically) and keep committing every frame there.

        Saving a map under the name it already commits to writes nothing unless `overwrite`
        (then the whole map is written afresh, which mends a file damaged on disk); a damaged
        file is refused rather than reported saved.

        Returns:
            (the live map, whether a file was written; False when it already commits there).

        Raises:
            InvalidInputError: a bad name.
            StoreError: `name` exists and `overwrite` is false, another map has it open, the
                file of the map itself is damaged and `overwrite` is false, or the write
                failed (the old file is then unchanged).
        """
        from glmap_tools.map.store import MapStore

        with self._lock:
            path = self.map_path(name)
            stem = path.name[: -len(MAP_SUFFIX)]
            live = session.live
            if live.name == stem and not overwrite:
                store = live.glmap.store
                damage = store.damage() if store is not None else None
                if damage is not None:
                    raise StoreError(
                        f"the file of map {stem!r} is damaged ({damage}) and was not saved; "
                        "pass overwrite=true to write the map in memory over it."
                    )
                return live, False
            other = self._named.get(stem)
            if other is not None and other is not live:
                raise StoreError(
                    f"map {stem!r} is open in another session; save under another name."
                )
            if path.exists() and not overwrite:
                raise StoreError(
                    f"a map named {stem!r} already exists; pass overwrite=true to replace it, "
                    "or choose another name."
                )
            make_folder(self.maps_dir)
            with live.lock, paths_hidden(self.maps_dir):
                old_store = live.glmap.store
                live.glmap.store = MapStore.create_from(path, live.glmap, overwrite=overwrite)
                if old_store is not None:
                    old_store.close()
            if live.name is not None:
                self._named.pop(live.name, None)
            live.name = stem
            self._named[stem] = live
            return live, True

    # ------------------------------------------------------------------ sessions
    def resolve(
        self, handle: str | None, transport_id: str | None, restart: bool = False
    ) -> Session:
        """The session a call belongs to (see the module docstring).

        Args:
            handle: the `session` argument of the call, if any.
            transport_id: the Mcp-Session-Id of a stateful HTTP connection, if any.
            restart: the call starts a map anew (new_map, load_map): a connection whose
                session was dropped gets a fresh one instead of an error.

        Raises:
            UnknownIdError: `handle` names no session, or the connection's session was
                dropped (its unsaved map with it); the message says what to do.
            StoreError: a new session is needed but every slot is in recent use.
        """
        with self._lock:
            session: Session | None
            if handle == DEFAULT_HANDLE or (handle is None and self.pin is not None):
                # Results name the default session, so it may be asked for by name; with
                # --map every connection works on the pinned map unless it names another.
                session = self.default_session()
            elif handle is not None:
                session = self._sessions.get(handle)
                if session is None:
                    why = (
                        f"was dropped: it had been idle longest when the server needed room "
                        f"for new sessions (at most {self.config.max_sessions}); its unsaved "
                        "map is gone"
                        if handle in self._dropped
                        else "does not exist"
                    )
                    raise UnknownIdError(
                        f"session {handle!r} {why}. Call new_map or load_map without a "
                        "session to start a new one, or omit session."
                    )
            elif transport_id is not None:
                key = self._by_transport.get(transport_id)
                session = self._sessions.get(key) if key else None
                if session is None:
                    if transport_id in self._dropped and not restart:
                        raise UnknownIdError(
                            "this connection's session was dropped: it had been idle longest "
                            "when the server needed room for new sessions (at most "
                            f"{self.config.max_sessions}), and its unsaved map is gone. Call "
                            "new_map or load_map to start again (save_map keeps a map)."
                        )
                    self._dropped.pop(transport_id, None)
                    session = self._create_session()
                    self._by_transport[transport_id] = session.handle
            else:
                session = self.default_session()
            session.last_used = time.monotonic()
        if session.handle == DEFAULT_HANDLE and self.pin is not None:
            self.pin.ensure(session)  # outside self._lock: the pin takes it after its own
        return session

    def default_session(self) -> Session:
        """The default session (made on first use, on a scratch map)."""
        with self._lock:
            return self._sessions.get(DEFAULT_HANDLE) or self._sessions.setdefault(
                DEFAULT_HANDLE, Session(DEFAULT_HANDLE, self._scratch())
            )

    def start_session(self) -> Session:
        """A new session with its own scratch map and a fresh unguessable handle."""
        with self._lock:
            return self._create_session()

    def _create_session(self) -> Session:
        self._evict(self.config.max_sessions - 1)
        handle = secrets.token_urlsafe(12)
        session = Session(handle, self._scratch())
        self._sessions[handle] = session
        return session

    def _evict(self, keep: int) -> None:
        """Drop least recently used sessions (never the default) until `keep` others remain.

        Only sessions idle for `session_protect_s` may go: one client starting many
        sessions cannot drop the maps of clients at work.

        Raises:
            StoreError: room is needed but every session was used too recently.
        """
        others = [s for h, s in self._sessions.items() if h != DEFAULT_HANDLE]
        others.sort(key=lambda s: s.last_used)
        now = time.monotonic()
        while len(others) > keep:
            victim = others[0]
            idle = now - victim.last_used
            if idle < self.config.session_protect_s:
                raise StoreError(
                    f"the server holds {len(others)} client sessions (its limit is "
                    f"{self.config.max_sessions}), all used in the last "
                    f"{self.config.session_protect_s:.0f} s; reuse your session handle "
                    "(pass session=...) instead of starting new ones, or try again later."
                )
            others.pop(0)
            del self._sessions[victim.handle]
            self._remember_dropped(victim.handle)
            for tid in [t for t, h in self._by_transport.items() if h == victim.handle]:
                del self._by_transport[tid]
                self._remember_dropped(tid)
            self._close_session(victim)

    def _remember_dropped(self, key: str) -> None:
        self._dropped[key] = time.monotonic()
        while len(self._dropped) > DROPPED_KEPT:
            self._dropped.popitem(last=False)

    def _close_session(self, session: Session) -> None:
        session.close()
        self._dropped_by(session)
        self._release(session.live)
        trim()

    def end_transport(self, transport_id: str) -> None:
        """The stateful HTTP session `transport_id` ended (DELETE, idle timeout): so does
        the session it made, with its pending frames and its map (a saved file stays)."""
        with self._lock:
            handle = self._by_transport.pop(transport_id, None)
            session = self._sessions.get(handle) if handle not in (None, DEFAULT_HANDLE) else None
            if session is not None:
                del self._sessions[session.handle]
                self._close_session(session)

    def close(self) -> None:
        """Close every session and map (lifespan exit)."""
        if self.pin is not None:
            self.pin.flush()
        with self._lock:
            for session in list(self._sessions.values()):
                self._close_session(session)
            self._sessions.clear()
            self._by_transport.clear()
