"""`glmap://` resources: saved maps, and per session the summary, units and top-down image.

URIs name the session: `glmap://{session}/...`, where `current` means the session of the
connection reading it (the default session over stdio). No `from __future__ import
annotations` here: the SDK reads these signatures at runtime.
"""

import json
from typing import TYPE_CHECKING

from mcp.server.mcpserver import Context, MCPServer
from mcp.server.mcpserver.exceptions import ResourceError, ResourceNotFoundError

from glmap_tools.app.config import ServerConfig
from glmap_tools.app.session import Session, locked
from glmap_tools.app.session import saved_maps as saved_map_files
from glmap_tools.app.views import EMPTY_MAP
from glmap_tools.app.views import topdown as draw
from glmap_tools.errors import GLMapError, UnknownIdError
from glmap_tools.map.queries import details
from glmap_tools.server.context import app_state, transport_of

if TYPE_CHECKING:
    from glmap_tools.map import GLMap

CURRENT = "current"


def _session(ctx: Context, handle: str) -> Session:
    transport_id, _ = transport_of(ctx)
    registry = app_state(ctx).registry
    try:
        return registry.resolve(None if handle == CURRENT else handle, transport_id)
    except UnknownIdError as exc:
        raise ResourceNotFoundError(str(exc)) from exc


def _unit_id(raw: str) -> int:
    try:
        uid = int(raw)
    except ValueError:
        raise ResourceNotFoundError(
            f"unit id {raw!r} is not an integer; use e.g. glmap://current/instances/3."
        ) from None
    return uid


def _unit_json(glmap: "GLMap", uid: int, kind: str) -> str:
    units = glmap.instances if kind == "instance" else glmap.regions
    unit = units.get(uid)
    if unit is None:
        try:
            glmap.unit(uid)  # raises with the closest id
        except UnknownIdError as exc:
            raise ResourceNotFoundError(str(exc)) from exc
        raise ResourceNotFoundError(f"unit {uid} is not an {kind}; it is the other kind.")
    return details(glmap, unit).model_dump_json()


def _index(glmap: "GLMap", kind: str) -> str:
    if kind == "instance":
        items = [
            {"id": u.id, "label": u.label, "centroid": [round(float(c), 3) for c in u.centroid]}
            for u in glmap.instances.values()
        ]
    else:
        items = [
            {"id": r.id, "description": r.text[:200], "instance_ids": list(r.instance_ids)}
            for r in glmap.regions.values()
        ]
    return json.dumps(items, separators=(",", ":"))


def register(server: MCPServer, config: ServerConfig) -> None:
    """Add the glmap:// resources to `server`."""

    @server.resource("glmap://maps", mime_type="application/json", name="saved maps")
    def saved_maps() -> str:
        """Names of the maps saved in the server's maps folder."""
        return json.dumps(sorted(saved_map_files(config.maps_dir)))

    @server.resource("glmap://{session}/summary", mime_type="application/json", name="map summary")
    def summary(session: str, ctx: Context) -> str:
        """Counts and bounds of a session's map (`current` = your session)."""
        target = _session(ctx, session)
        with locked(target) as glmap:
            return glmap.summary().model_dump_json()

    @server.resource(
        "glmap://{session}/instances", mime_type="application/json", name="instance index"
    )
    def instances(session: str, ctx: Context) -> str:
        """Id, label and centroid of every instance of a session's map."""
        target = _session(ctx, session)
        with locked(target) as glmap:
            return _index(glmap, "instance")

    @server.resource("glmap://{session}/regions", mime_type="application/json", name="region index")
    def regions(session: str, ctx: Context) -> str:
        """Id, description and members of every region of a session's map."""
        target = _session(ctx, session)
        with locked(target) as glmap:
            return _index(glmap, "region")

    @server.resource(
        "glmap://{session}/instances/{unit_id}", mime_type="application/json", name="instance"
    )
    def instance(session: str, unit_id: str, ctx: Context) -> str:
        """One instance: description, centroid, bounds, observations, regions."""
        target = _session(ctx, session)
        with locked(target) as glmap:
            return _unit_json(glmap, _unit_id(unit_id), "instance")

    @server.resource(
        "glmap://{session}/regions/{unit_id}", mime_type="application/json", name="region"
    )
    def region(session: str, unit_id: str, ctx: Context) -> str:
        """One region: description, centroid, bounds, member instances."""
        target = _session(ctx, session)
        with locked(target) as glmap:
            return _unit_json(glmap, _unit_id(unit_id), "region")

    @server.resource("glmap://{session}/topdown.png", mime_type="image/png", name="top-down map")
    def topdown(session: str, ctx: Context) -> bytes:
        """The top-down map image (free space, obstacles, instances, regions, trajectory)."""
        target = _session(ctx, session)
        try:
            with locked(target) as glmap:
                image = draw(glmap)
        except GLMapError as exc:
            raise ResourceError(str(exc)) from exc
        if image is None:
            raise ResourceError("no top-down image yet: " + EMPTY_MAP)
        return image.to_png()
