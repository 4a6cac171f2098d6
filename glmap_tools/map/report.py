"""Results of map updates and queries (pydantic, so every edge can serialise them)."""

from __future__ import annotations

from pydantic import BaseModel, Field, field_validator

DECIMALS = 4  # metres to 0.1 mm: enough for any map, no float32 noise in the output


class UnitChange(BaseModel):
    """One unit added or merged by a frame."""

    local_id: int = Field(description="id of the observation within the frame")
    global_id: int = Field(description="stable id of the unit in the map")
    text: str = Field(description="the observed description")
    similarity: float | None = Field(
        default=None, description="text cosine to the unit it merged into (merges only)"
    )


class SkippedObservation(BaseModel):
    """An observation the frame could not turn into a unit, and why."""

    local_id: int
    kind: str = Field(description="'instance' or 'region'")
    reason: str


class UpdateReport(BaseModel):
    """What `GLMap.integrate` did with one frame."""

    frame_index: int
    instances_added: list[UnitChange] = Field(default_factory=list)
    instances_merged: list[UnitChange] = Field(default_factory=list)
    regions_added: list[UnitChange] = Field(default_factory=list)
    regions_merged: list[UnitChange] = Field(default_factory=list)
    skipped: list[SkippedObservation] = Field(default_factory=list)
    local_to_global: dict[int, int] = Field(
        default_factory=dict, description="instance local id -> global id (the mapping T_t)"
    )
    fused: dict[int, int] = Field(
        default_factory=dict,
        description="id of a unit fused into an older unit of the same object or region -> "
        "the older unit's id; the fused id no longer exists",
    )
    gaussians_added: int = 0
    structure_gaussians: int = Field(
        default=0, description="structure (background) Gaussians fitted from this frame"
    )
    num_instances: int = 0
    num_regions: int = 0

    def summary(self) -> str:
        return (
            f"frame {self.frame_index}: +{len(self.instances_added)} instances, "
            f"{len(self.instances_merged)} merged; +{len(self.regions_added)} regions, "
            f"{len(self.regions_merged)} merged; {len(self.skipped)} skipped; map has "
            f"{self.num_instances} instances, {self.num_regions} regions"
        )


class UnitInfo(BaseModel):
    """A unit as queries return it."""

    id: int
    kind: str = Field(description="'instance' or 'region'")
    label: str = Field(default="", description="short category (instances)")
    description: str = Field(description="the unit's text buffer T")
    score: float | None = Field(
        default=None, description="similarity to the query in [-1, 1], if any (higher is closer)"
    )
    match: bool | None = Field(
        default=None,
        description="the score reaches the calibrated match threshold: false means the map "
        "has nothing that fits the query well (text queries only)",
    )
    distance: float | None = Field(default=None, description="metres from the query point")
    centroid: list[float] = Field(description="[x, y, z] metres, world z-up")
    bounds: list[list[float]] = Field(description="[[xmin, ymin, zmin], [xmax, ymax, zmax]]")
    observations: int = Field(description="frames that observed the unit")
    num_gaussians: int = 0
    instance_ids: list[int] = Field(default_factory=list, description="members (regions)")
    region_ids: list[int] = Field(default_factory=list, description="regions it belongs to")


class MapSummary(BaseModel):
    """Counts and extent of a map."""

    instances: int
    regions: int
    gaussians: int
    gaussian_bytes: int
    structure_gaussians: int = Field(
        default=0, description="Gaussians of the structure background layer (not units)"
    )
    frames: int = Field(description="frames integrated")
    grid_cells: int = Field(description="occupied index-grid cells")
    floor_z: float | None = Field(description="floor height (m), estimated or configured")
    bounds: list[list[float]] | None = Field(
        default=None, description="[[xmin, ymin, zmin], [xmax, ymax, zmax]] of all instances"
    )

    @field_validator("floor_z")
    @classmethod
    def _round_floor(cls, v: float | None) -> float | None:
        return None if v is None else round(float(v), DECIMALS)

    @field_validator("bounds")
    @classmethod
    def _round_bounds(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        return None if v is None else [[round(float(x), DECIMALS) for x in row] for row in v]
