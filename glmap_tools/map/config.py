"""`MapConfig`: every tunable of a GLMap in one place (saved with the map)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from glmap_tools.errors import InvalidInputError
from glmap_tools.limits import MAX_COORDINATE

# metres: a voxel or cell past these makes a meaningless map (a 1e20 m voxel asked for
# 166 PiB of grid cells), or a grid too fine for memory over `max_span`
EDGE_RANGES = {
    "voxel_size": (0.001, 1.0),
    "cell_size": (0.01, 1.0),
    "structure_voxel": (0.005, 1.0),
}


@dataclass(frozen=True)
class MapConfig:
    """Settings of a GLMap.

    Attributes:
        voxel_size: Gaussian Estimator voxel edge (m), in [0.001, 1].
        cell_size: index-grid and occupancy cell edge (m), in [0.01, 1].
        tau_s: text-similarity threshold; None = the embedder's calibrated default.
        max_text_words: text buffer length that triggers the text merger.
        max_range: depth beyond this (m) is ignored.
        floor_z: world height of the floor (m); None = estimated from observed points.
        obstacle_band: heights above the floor (m) whose points mark obstacles.
        camera_height: agent camera height above the floor (m), for rendered views.
        occupancy_stride: pixel stride for the occupancy update.
        structure_voxel: voxel edge (m, in [0.005, 1]) of the structure background layer
            (pixels in no object mask); None keeps no structure. See map/structure.py for
            the 5 cm.
        structure_stride: pixel stride for the structure layer's points; 0 = about 160
            columns whatever the image width (stride 2 at 320 x 240, 4 at 640 x 480).
        world_limit: every camera centre and observed point lies within this many metres
            of the origin on each axis (x, y, z); a frame reaching farther is refused.
        max_span: the map's extent on each axis, over its camera centres and the points of
            a new frame, is at most this (m); a frame that would stretch it is refused.
            See map/bounds.py.
        estimator: extra keyword overrides for the Gaussian Estimator config.
    """

    voxel_size: float = 0.02
    cell_size: float = 0.05
    tau_s: float | None = None
    max_text_words: int = 300
    max_range: float = 5.0
    floor_z: float | None = None
    obstacle_band: tuple[float, float] = (0.10, 1.50)
    camera_height: float = 0.88
    occupancy_stride: int = 2
    structure_voxel: float | None = 0.05
    structure_stride: int = 0
    world_limit: float = 1000.0
    max_span: float = 200.0
    estimator: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        positive = ("voxel_size", "cell_size", "max_range", "camera_height")
        for name in (*positive, "world_limit", "max_span"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (
                isinstance(value, int | float) and 0 < value < math.inf
            ):
                raise InvalidInputError(
                    f"MapConfig.{name}={value!r} must be a positive finite number."
                )
        for name, (low, high) in EDGE_RANGES.items():
            value = getattr(self, name)
            if isinstance(value, int | float) and not low <= value <= high:
                raise InvalidInputError(
                    f"MapConfig.{name}={value!r} m must lie in [{low}, {high}] m (the default "
                    f"is {getattr(MapConfig, name)}); check the units are metres."
                )
        if self.world_limit > MAX_COORDINATE:
            raise InvalidInputError(
                f"MapConfig.world_limit={self.world_limit!r} must be <= {MAX_COORDINATE:g} m."
            )
        if self.tau_s is not None and not (
            isinstance(self.tau_s, int | float)
            and not isinstance(self.tau_s, bool)
            and -1.0 <= self.tau_s <= 1.0
        ):
            raise InvalidInputError(f"MapConfig.tau_s={self.tau_s!r} must be a cosine in [-1, 1].")
        if not (isinstance(self.max_text_words, int) and self.max_text_words >= 10):
            raise InvalidInputError(
                f"MapConfig.max_text_words={self.max_text_words!r} must be an integer >= 10."
            )
        band = self.obstacle_band
        numbers_ok = isinstance(band, tuple | list) and len(band) == 2
        numbers_ok = numbers_ok and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in band
        )
        if not numbers_ok:
            raise InvalidInputError(
                f"MapConfig.obstacle_band={band!r} must be (low, high) metres above the floor, "
                f"e.g. {MapConfig.obstacle_band}."
            )
        low, high = band
        if not (0 <= low < high):
            raise InvalidInputError(
                f"MapConfig.obstacle_band={self.obstacle_band!r} "
                "must be (low, high) with 0 <= low < high."
            )
        if not (isinstance(self.occupancy_stride, int) and self.occupancy_stride >= 1):
            raise InvalidInputError(
                f"MapConfig.occupancy_stride={self.occupancy_stride!r} must be an integer >= 1."
            )
        if self.structure_voxel is not None and not (
            isinstance(self.structure_voxel, int | float) and self.structure_voxel > 0
        ):
            raise InvalidInputError(
                f"MapConfig.structure_voxel={self.structure_voxel!r} must be a positive voxel "
                "edge in metres (e.g. 0.05) or None for no structure layer."
            )
        if not (isinstance(self.structure_stride, int) and self.structure_stride >= 0):
            raise InvalidInputError(
                f"MapConfig.structure_stride={self.structure_stride!r} must be an integer >= 1, "
                "or 0 for about 160 columns per image."
            )
        if not isinstance(self.estimator, dict):
            raise InvalidInputError(
                f"MapConfig.estimator={self.estimator!r} must be a dict of EstimatorConfig "
                'settings, e.g. {"tau": -20}.'
            )
        object.__setattr__(self, "obstacle_band", (float(low), float(high)))

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["obstacle_band"] = list(self.obstacle_band)
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MapConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise InvalidInputError(
                f"unknown MapConfig keys {sorted(unknown)}; known keys are {sorted(known)}."
            )
        d = dict(data)
        if "obstacle_band" in d:
            d["obstacle_band"] = tuple(d["obstacle_band"])
        return cls(**d)
