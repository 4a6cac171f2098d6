"""Map-store tools: new_map, save_map, load_map, list_maps (names only, in the maps folder).

No `from __future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

import datetime as dt
from typing import Annotated

from pydantic import Field

from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.results import MapEntry, MapInfo, MapList, SavedMap
from glmap_tools.app.runtime import (
    DROPS,
    READ_ONLY,
    REPLACES,
    Call,
    ToolSpec,
    in_thread,
    session_for_new_map,
    session_of,
)
from glmap_tools.app.session import Session, locked, saved_maps
from glmap_tools.app.tools_map import resource_uris

MapName = Annotated[
    str, Field(min_length=1, max_length=70, description="letters, digits, '-' or '_'")
]


# A loaded map is the user's saved work: simulator frames never go into it unasked.
EPISODE_ENDED = (
    "the simulator episode was ended: its frames stay in the map it was building, never in "
    "a loaded one; sim_reset starts a new episode (keep_map=true adds its frames to this map)"
)


def _info(session: Session) -> MapInfo:
    with locked(session) as glmap:
        return MapInfo(
            session=session.handle,
            map_name=session.live.name,
            summary=glmap.summary(),
            resources=resource_uris(session.handle),
        )


async def new_map(
    call: Call,
    name: Annotated[
        str, Field(max_length=70, description="save under this name; omit: scratch map")
    ] = "",
    session: SessionArg = "",
) -> MapInfo:
    """Start an empty map (the current one is dropped unless saved). Over shared HTTP it is
    a new session: pass its handle as `session`."""
    target = session_for_new_map(call, session)
    registry = call.state.registry

    def run() -> MapInfo:
        registry.new_map(target, name or None)
        return _info(target)

    return await in_thread(run)


async def save_map(
    name: MapName,
    call: Call,
    overwrite: bool = False,
    session: SessionArg = "",
) -> SavedMap:
    """Save the map under a name (overwrite: replace one); later frames are committed too."""
    target = session_of(call, session)
    registry = call.state.registry

    def run() -> SavedMap:
        live, written = registry.save_map(target, name, overwrite)
        path = registry.map_path(live.name or name)
        return SavedMap(
            session=target.handle,
            map_name=live.name,
            written=written,
            bytes=path.stat().st_size,
        )

    return await in_thread(run)


async def load_map(name: MapName, call: Call, session: SessionArg = "") -> MapInfo:
    """Open a saved map (the current one is dropped unless saved); sessions share it."""
    target = session_for_new_map(call, session)
    registry = call.state.registry

    def run() -> MapInfo:
        with target.sim_lock:  # a sim_step in flight finishes first
            before = target.live
            registry.load_map(target, name)
            ended = target.sim is not None and target.live is not before
            if ended:
                target.end_episode()
        info = _info(target)
        if ended:
            info.simulator = EPISODE_ENDED
        return info

    return await in_thread(run)


async def list_maps(call: Call) -> MapList:
    """List the saved maps (open one with load_map)."""
    registry = call.state.registry

    def run() -> MapList:
        open_names = registry.open_names()
        entries = []
        for name, stat in sorted(saved_maps(registry.maps_dir).items()):
            modified = dt.datetime.fromtimestamp(stat.st_mtime, dt.UTC)
            entries.append(
                MapEntry(
                    name=name,
                    bytes=stat.st_size,
                    modified=modified.isoformat(timespec="seconds"),
                    open=name in open_names,
                )
            )
        return MapList(maps=entries)

    return await in_thread(run)


TOOLS = [
    ToolSpec(new_map, DROPS),
    ToolSpec(save_map, REPLACES),
    ToolSpec(load_map, REPLACES),
    ToolSpec(list_maps, READ_ONLY),
]
