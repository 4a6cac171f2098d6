"""`MapState`: what a GLMap holds (its units, index grid, occupancy, structure layer,
trajectory, the models it fuses with) and the lookups over it. Fusion, the queries and the
store work on a `MapState`; `GLMap` adds integrating, persistence and the queries' API."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.checks import is_integer
from glmap_tools.errors import InvalidInputError, UnknownIdError, did_you_mean
from glmap_tools.gaussians.config import EstimatorConfig
from glmap_tools.gaussians.estimator import GaussianEstimator
from glmap_tools.map.config import MapConfig
from glmap_tools.map.grid import IndexGrid, unit_cells
from glmap_tools.map.occupancy import OccupancyGrid
from glmap_tools.map.structure import StructureLayer
from glmap_tools.map.units import InstanceUnit, RegionUnit


def check_parts(config: object, embedder: object) -> None:
    """Refuse a config that is not a MapConfig or an embedder that is not an Embedder (None
    is each one's default)."""
    if config is not None and not isinstance(config, MapConfig):
        raise InvalidInputError(
            f"config is {type(config).__name__}, not MapConfig; pass MapConfig(...) or None "
            "for the defaults (MapConfig.from_dict reads a dict)."
        )
    if embedder is not None and not all(
        hasattr(embedder, a) for a in ("embed", "dim", "name", "default_tau_s")
    ):
        raise InvalidInputError(
            f"embedder is {type(embedder).__name__}, not an Embedder (embed, dim, name, "
            "default_tau_s); pass e.g. MiniLMEmbedder() or HashingEmbedder(), or None."
        )


def unit_id_of(value: object) -> int:
    """`value` as a unit id (an integer, numpy's included).

    Raises:
        InvalidInputError: anything else (a bool, a float, a string, ...).
    """
    if is_integer(value):
        return int(value)
    raise InvalidInputError(
        f"unit id {value!r} is not an integer; give the id of an instance or region, as "
        "find_instances, find_regions or units_at report it."
    )


if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.language.text_merger import TextMerger

# Imports inside functions stay there: language.embed load on first use.

Unit = InstanceUnit | RegionUnit


class MapState:
    """The state of a Gaussian-Language Map and its lookups (see `GLMap`).

    Args:
        config: map settings (saved with the map).
        embedder: text embedder phi; default: the bundled all-MiniLM-L6-v2, loaded lazily.
        text_merger: rewrites text buffers past `config.max_text_words`; default extractive.
    """

    def __init__(
        self,
        config: MapConfig | None = None,
        embedder: Embedder | None = None,
        text_merger: TextMerger | None = None,
    ) -> None:
        check_parts(config, embedder)
        self.config = config or MapConfig()
        if embedder is None:
            # Imported here so the core does not load a model library unless asked to.
            from glmap_tools.language.minilm import default_embedder

            embedder = default_embedder()
        self.embedder: Embedder = embedder
        if text_merger is None:
            from glmap_tools.language.text_merger import ExtractiveTextMerger

            text_merger = ExtractiveTextMerger(embedder)
        self.text_merger: TextMerger = text_merger
        self.tau_s = self.config.tau_s if self.config.tau_s is not None else embedder.default_tau_s
        self.estimator = GaussianEstimator(
            EstimatorConfig(voxel_size=self.config.voxel_size, **self.config.estimator)
        )
        self.instances: dict[int, InstanceUnit] = {}
        self.regions: dict[int, RegionUnit] = {}
        self.grid = IndexGrid(self.config.cell_size)
        self.occupancy = OccupancyGrid(self.config.cell_size)
        structure_voxel = self.config.structure_voxel or self.config.voxel_size
        self.structure = StructureLayer(structure_voxel)
        # One Gaussian per coarse voxel (merge off), so the layer merges per voxel.
        self.structure_estimator = GaussianEstimator(
            EstimatorConfig(voxel_size=structure_voxel, merge=False)
        )
        self.next_id = 1
        self.floor_z: float | None = self.config.floor_z
        self.trajectory: list[np.ndarray] = []  # [4, 4] poses of integrated frames
        self._regions_by_instance: dict[int, set[int]] = {}
        self.fused_into: dict[int, int] = {}  # fused id -> the unit it became (this process)
        self._matrix_cache: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def _restore(
        self,
        instances: dict[int, InstanceUnit],
        regions: dict[int, RegionUnit],
        occupancy: OccupancyGrid,
        structure: StructureLayer,
        next_id: int,
        floor_z: float | None,
        trajectory: list[np.ndarray],
    ) -> None:
        """Install loaded state and derive the index grid and reverse indices from it."""
        self.instances, self.regions = dict(instances), dict(regions)
        self.occupancy, self.next_id, self.floor_z = occupancy, next_id, floor_z
        self.structure = structure
        self.trajectory = list(trajectory)
        self.grid = IndexGrid(self.config.cell_size)
        for uid, unit in self.instances.items():
            self.grid.set_unit(uid, unit_cells(unit.gaussians, self.config.cell_size))
        self._regions_by_instance = {}
        for rid, region in self.regions.items():
            cells_of_region: set[tuple[int, int]] = set()
            for iid in region.instance_ids:
                self._regions_by_instance.setdefault(iid, set()).add(rid)
                cells_of_region |= self.grid.cells_of_unit(iid)
            self.grid.set_unit(rid, cells_of_region)
        self._matrix_cache.clear()

    # ----------------------------------------------------------------- lookups
    def regions_of_instance(self, instance_id: int) -> set[int]:
        return set(self._regions_by_instance.get(unit_id_of(instance_id), ()))

    def _matrix(self, kind: str) -> tuple[np.ndarray, np.ndarray]:
        cached = self._matrix_cache.get(kind)
        if cached is None:
            units: dict[int, InstanceUnit] | dict[int, RegionUnit] = (
                self.instances if kind == "instance" else self.regions
            )
            ids = np.array(sorted(units), dtype=np.int64)
            if len(ids):
                matrix = np.stack([units[int(i)].embedding for i in ids]).astype(np.float32)
            else:
                matrix = np.zeros((0, self.embedder.dim), np.float32)
            cached = self._matrix_cache[kind] = (ids, matrix)
        return cached

    def instance_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids [N], embeddings [N, D]) of all instances, cached between updates."""
        return self._matrix("instance")

    def region_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids [M], embeddings [M, D]) of all regions, cached between updates."""
        return self._matrix("region")

    def unit(self, unit_id: int) -> Unit:
        """The instance or region with this id.

        Raises:
            UnknownIdError: no such unit; the message names the unit a fused id became, or
                suggests the closest existing id.
        """
        unit_id = unit_id_of(unit_id)
        found = self.instances.get(unit_id) or self.regions.get(unit_id)
        if found is None and unit_id in self.fused_into:
            live = unit_id
            while live in self.fused_into:
                live = self.fused_into[live]
            raise UnknownIdError(
                f"unit id {unit_id!r} was fused into unit {live} (the same object or region "
                f"seen again); use id {live}."
            )
        if found is None:
            ids = sorted(self.instances) + sorted(self.regions)
            if not ids:
                raise UnknownIdError(f"unit id {unit_id!r} does not exist: the map is empty.")
            closest = min(ids, key=lambda i: (abs(i - int(unit_id)), i))
            hint = did_you_mean(str(unit_id), [str(i) for i in ids]) or f" Closest id: {closest}."
            raise UnknownIdError(
                f"unit id {unit_id!r} does not exist (the map has {len(self.instances)} "
                f"instances and {len(self.regions)} regions).{hint}"
            )
        return found
