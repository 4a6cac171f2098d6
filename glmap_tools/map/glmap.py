"""`GLMap`: the Multi-Scale Gaussian-Language Map M = {m, S_o, S_r}."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.map import queries
from glmap_tools.map.bounds import check_frame_bounds
from glmap_tools.map.config import MapConfig
from glmap_tools.map.fusion import FramePlan, plan_frame
from glmap_tools.map.occupancy import OccupancyGrid
from glmap_tools.map.report import MapSummary, UnitInfo, UpdateReport
from glmap_tools.map.state import MapState, Unit, check_parts
from glmap_tools.map.store import MapStore
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.perception.semantics import FrameSemantics

if TYPE_CHECKING:
    from collections.abc import Callable

    from glmap_tools.language.embed import Embedder
    from glmap_tools.language.text_merger import TextMerger

__all__ = ["GLMap", "Unit"]


class GLMap(MapState):
    """A Gaussian-Language Map, built frame by frame and queried by text or position.

    Besides the semantic units it keeps `structure`, a background layer of coarse
    Gaussians for every observed surface no object mask covers (walls, floor): rendered
    and occluding in views, never a unit (see map/structure.py).

    Args: as `MapState` (config, embedder, text_merger).
    """

    store: MapStore | None = None  # the SQLite file frames are committed to, if any

    # ----------------------------------------------------------------- persistence
    @classmethod
    def open(
        cls,
        path: str | os.PathLike[str],
        config: MapConfig | None = None,
        embedder: Embedder | None = None,
        text_merger: TextMerger | None = None,
    ) -> GLMap:
        """Open the map stored at `path`, or create it there; every integrate then commits.

        Raises:
            StoreError: the file exists but is not a GLMap store, or is from a newer version.
        """

        check_parts(config, embedder)  # before any file is made
        store = MapStore.open(path, create_with=config or MapConfig())
        try:
            glmap = cls(store.config, embedder, text_merger)
            store.load_into(glmap)
        except BaseException:
            store.close()
            raise
        glmap.store = store
        return glmap

    def save_as(self, path: str | os.PathLike[str]) -> None:
        """Write the whole map to a new store file at `path` and keep committing there."""

        self.store = MapStore.create_from(path, self)

    def close(self) -> None:
        if self.store is not None:
            self.store.close()
            self.store = None

    # ----------------------------------------------------------------- update
    def integrate(
        self,
        frame: RGBDFrame,
        semantics: FrameSemantics,
        frame_index: int | None = None,
        planner: Callable[[MapState, RGBDFrame, FrameSemantics, int], FramePlan] = plan_frame,
    ) -> UpdateReport:
        """Fuse one posed RGB-D frame and its semantics into the map (paper §3.1).

        Validation and all computation happen first; the store commits in one transaction;
        only then does the map in memory change. On any error nothing changes.

        Args:
            planner: computes the frame's changes (`map.fusion.plan_frame`; the replay check
                passes an older checkout's to compare the two).

        Returns:
            The update report: units added and merged, the local -> global id mapping.
        """
        if not isinstance(frame, RGBDFrame):
            raise InvalidInputError(f"frame must be an RGBDFrame, got {type(frame).__name__}.")
        check_frame_bounds(frame, self.config, self.trajectory)  # world_limit, max_span
        index = len(self.trajectory) if frame_index is None else int(frame_index)
        plan = planner(self, frame, semantics, index)
        if self.store is not None:
            self.store.commit_frame(plan, self)
        self._apply(plan)
        assert plan.report is not None
        return plan.report

    def _apply(self, plan: FramePlan) -> None:
        for uid, unit in plan.instances.items():
            self.instances[uid] = unit
        for rid, region in plan.regions.items():
            old = self.regions.get(rid)
            for iid in old.instance_ids if old else ():
                self._regions_by_instance.get(iid, set()).discard(rid)
            for iid in region.instance_ids:
                self._regions_by_instance.setdefault(iid, set()).add(rid)
            self.regions[rid] = region
        if plan.report is not None:
            self.fused_into.update(plan.report.fused)
        for uid in sorted(plan.removed):  # fused into an older unit
            gone = self.regions.pop(uid, None)
            for iid in gone.instance_ids if gone else ():
                self._regions_by_instance.get(iid, set()).discard(uid)
            self.instances.pop(uid, None)
            self._regions_by_instance.pop(uid, None)
            self.grid.remove_unit(uid)
        for uid, cells in plan.cells.items():
            self.grid.set_unit(uid, cells)
        self.occupancy.apply(plan.occupancy)
        self.structure.apply(plan.structure)
        self.next_id = plan.next_id
        self.floor_z = plan.floor_z
        self.trajectory.append(plan.pose)
        self._matrix_cache.clear()

    @classmethod
    def from_units(
        cls,
        instances: dict[int, InstanceUnit],
        regions: dict[int, RegionUnit],
        next_id: int,
        config: MapConfig | None = None,
        embedder: Embedder | None = None,
    ) -> GLMap:
        """An in-memory map holding exactly these units (no frames, empty occupancy).

        For benchmarks and evaluations that build maps from ground truth; the index grid
        comes from the units' Gaussians as when a saved map is opened.
        """
        config = config or MapConfig()
        glmap = cls(config, embedder=embedder)
        glmap._restore(
            instances=instances,
            regions=regions,
            occupancy=OccupancyGrid(config.cell_size),
            structure=glmap.structure,
            next_id=next_id,
            floor_z=0.0,
            trajectory=[],
        )
        return glmap

    def summary(self) -> MapSummary:
        """Counts and bounds of the map."""
        n_gauss = sum(len(u.gaussians) for u in self.instances.values())
        bounds = None
        if self.instances:
            lo = np.min([u.bounds()[0] for u in self.instances.values()], axis=0)
            hi = np.max([u.bounds()[1] for u in self.instances.values()], axis=0)
            bounds = [lo.round(3).tolist(), hi.round(3).tolist()]
        return MapSummary(
            instances=len(self.instances),
            regions=len(self.regions),
            gaussians=n_gauss,
            gaussian_bytes=sum(u.gaussians.nbytes for u in self.instances.values()),
            structure_gaussians=len(self.structure),
            frames=len(self.trajectory),
            grid_cells=len(self.grid),
            floor_z=self.floor_z,
            bounds=bounds,
        )

    # ----------------------------------------------------------------- queries
    def find_instances(self, text: str, k: int = 5) -> list[UnitInfo]:
        """The k instances whose descriptions are most similar to `text`, best first."""
        return queries.find(self, "instance", text, k)

    def find_regions(self, text: str, k: int = 5) -> list[UnitInfo]:
        """The k regions whose descriptions are most similar to `text`, best first."""
        return queries.find(self, "region", text, k)

    def units_at(self, x: float, y: float, radius: float = 0.25) -> list[UnitInfo]:
        """Units with a grid cell within `radius` m of (x, y), nearest first."""
        return queries.units_at(self, x, y, radius)

    def unit_details(self, unit_id: int) -> UnitInfo:
        """Centroid, bounds, description and observation count of one unit."""
        return queries.details(self, self.unit(unit_id))
