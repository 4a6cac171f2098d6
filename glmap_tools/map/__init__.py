"""The map: units, index grid, occupancy, incremental fusion, queries, SQLite store."""

from glmap_tools.map.config import MapConfig
from glmap_tools.map.glmap import GLMap
from glmap_tools.map.grid import IndexGrid
from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, OccupancyGrid
from glmap_tools.map.report import UnitInfo, UpdateReport
from glmap_tools.map.units import InstanceUnit, RegionUnit

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
