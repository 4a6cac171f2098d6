"""Limits that light modules check too: the map's settings, read by every launch, need no numpy."""

# Camera centres lie within MAX_COORDINATE metres of the origin (a map bounds its own world
# more tightly: MapConfig.world_limit).
MAX_COORDINATE = 1e6
