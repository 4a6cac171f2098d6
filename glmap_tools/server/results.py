"""Pydantic results of the MCP tools (their output schemas); each field is described."""

from __future__ import annotations

from pydantic import BaseModel, Field

from glmap_tools.map.report import MapSummary, UnitInfo, UpdateReport


class SessionInfo(BaseModel):
    """Which session and map a call worked on."""

    session: str = Field(
        description="session handle; pass it as `session` to later calls when several "
        "clients share a stateless server (not needed over stdio)"
    )
    map_name: str | None = Field(
        description="saved map this session works on (every frame is committed to it), or "
        "null for an unsaved scratch map"
    )


class ObserveResult(SessionInfo):
    """What one observed frame changed in the map."""

    summary: str = Field(description="one line: units added and merged, map size")
    report: UpdateReport = Field(description="instances and regions added or merged, with ids")


class Hits(BaseModel):
    """Ranked matches of a text query, best first."""

    query: str
    hits: list[UnitInfo] = Field(
        description="id, description, score (text cosine), centroid, bounds; regions list "
        "their member instance_ids"
    )


class UnitsAt(BaseModel):
    """The units around a point of the floor plan, nearest first."""

    x: float
    y: float
    radius: float
    occupancy: str = Field(description="'free', 'obstacle' or 'unknown' at (x, y)")
    units: list[UnitInfo] = Field(description="`distance` is metres from (x, y) to the unit")


class MapInfo(SessionInfo):
    """Counts and extent of the session's map."""

    summary: MapSummary
    resources: list[str] = Field(description="glmap:// resources to read this map")


class SavedMap(SessionInfo):
    """The result of save_map."""

    written: bool = Field(description="false when the map already commits every frame to this name")
    bytes: int = Field(description="size of the map file")


class MapEntry(BaseModel):
    """One saved map in the maps folder."""

    name: str
    bytes: int
    modified: str = Field(description="ISO 8601 time of the last write (UTC)")
    open: bool = Field(description="open in some session right now")


class MapList(BaseModel):
    """The saved maps (names only; no paths are accepted or shown)."""

    maps: list[MapEntry]


class Exported(SessionInfo):
    """The result of export_ply."""

    file: str = Field(description="the file written, in the server's maps folder")
    what: str = Field(description="'whole map', 'instance 3 (chair)' or 'region 9'")
    gaussians: int = Field(description="number of 3D Gaussians in the file")
    instance_ids: list[int] = Field(description="the instances whose Gaussians it holds")
    bytes: int = Field(description="size of the file")
