"""The map: units, index grid, occupancy, incremental fusion, queries, SQLite store."""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.lazy import lazy_getattr

if TYPE_CHECKING:
    from glmap_tools.map.config import MapConfig
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.map.grid import IndexGrid
    from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, OccupancyGrid
    from glmap_tools.map.report import UnitInfo, UpdateReport
    from glmap_tools.map.units import InstanceUnit, RegionUnit

# Names load their submodule on first use, so importing one light part (say the report
# models) does not import them all (scipy, numba): the MCP server answers its handshake
# before the heavy parts load.
_LAZY = {
    "MapConfig": "glmap_tools.map.config",
    "GLMap": "glmap_tools.map.glmap",
    "IndexGrid": "glmap_tools.map.grid",
    "FREE": "glmap_tools.map.occupancy",
    "OBSTACLE": "glmap_tools.map.occupancy",
    "UNKNOWN": "glmap_tools.map.occupancy",
    "OccupancyGrid": "glmap_tools.map.occupancy",
    "UnitInfo": "glmap_tools.map.report",
    "UpdateReport": "glmap_tools.map.report",
    "InstanceUnit": "glmap_tools.map.units",
    "RegionUnit": "glmap_tools.map.units",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = [
    "FREE",
    "OBSTACLE",
    "UNKNOWN",
    "GLMap",
    "IndexGrid",
    "InstanceUnit",
    "MapConfig",
    "OccupancyGrid",
    "RegionUnit",
    "UnitInfo",
    "UpdateReport",
]
