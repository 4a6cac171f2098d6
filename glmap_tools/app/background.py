"""Slow start-up work done in the background, so `glmap-mcp` answers its handshake at once.

Loading the MiniLM embedder (torch, ~10 s) and compiling or loading the numba kernels
(estimator, fusion, splatting) used to run before the server answered `initialize`; MCP
clients that wait 5 s (pydantic-ai) or 15 s (the Inspector) gave up. Now the lifespan starts
them on daemon threads and returns; a tool call that arrives before they finish waits for
them, and says so (a progress notification and a line on stderr). `glmap-mcp --prepare`
runs the same work once in the foreground, so `.ci/setup` fills numba's on-disk cache
(every kernel uses cache=True).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools import synthetic
from glmap_tools.errors import GLMapError

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder

# Imports inside functions stay there: cv2, gaussians, language.embed, scipy load on first use:
# build_server stays light (test_server_startup): the server loads them in the background or on
# first use; the tools load before these do, in the server and the in-process toolset alike.

logger = logging.getLogger(__name__)

# glmap-mcp's start-up work waits up to this long for the first tools/list (or call), so that
# its imports (torch) do not take the interpreter from the handshake on a busy machine.
HANDSHAKE_HOLD_S = 2.0
WARM_VIEW = (128, 96)  # warm_kernels' frames: the chair gets ~1100 points, enough to merge
EMBEDDER = "embedder"
KERNELS = "kernels"
WHAT = {
    EMBEDDER: "loading the text embedder",
    KERNELS: "loading the compiled map and render kernels",
}


class Task:
    """One piece of start-up work on a daemon thread; `wait()` re-raises its error."""

    def __init__(
        self,
        name: str,
        fn: Callable[[], Any],
        gate: threading.Event | None = None,
        hold_s: float = 0.0,
    ) -> None:
        self.name = name
        self.started = time.perf_counter()
        self._gate = gate
        self._hold_s = hold_s
        self.seconds: float | None = None
        self._done = threading.Event()
        self._value: Any = None
        self._error: BaseException | None = None
        self._fn = fn
        threading.Thread(target=self._run, name=f"glmap-{name}", daemon=True).start()

    def _run(self) -> None:
        if self._gate is not None and self._hold_s > 0:
            self._gate.wait(self._hold_s)
            self.started = time.perf_counter()
        try:
            self._value = self._fn()
        except BaseException as exc:  # re-raised in every waiting call
            self._error = exc
            logger.error("glmap-mcp: %s failed: %s", WHAT.get(self.name, self.name), exc)
        finally:
            self.seconds = time.perf_counter() - self.started
            self._done.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def wait(self) -> Any:
        """Block until the work is done; return its value or raise its error."""
        self._done.wait()
        if self._error is not None:
            raise self._error
        return self._value


class Background:
    """The named start-up tasks of one server process."""

    def __init__(self, hold_s: float = 0.0) -> None:
        """`hold_s`: tasks start after `release()` or after this many seconds (0: at once)."""
        self.tasks: dict[str, Task] = {}
        self.hold_s = hold_s
        self._released = threading.Event()

    def start(self, name: str, fn: Callable[[], Any]) -> Task:
        task = Task(name, fn, self._released, self.hold_s)
        self.tasks[name] = task
        return task

    def release(self) -> None:
        """Let held tasks start now (the handshake is answered, or a call needs them)."""
        self._released.set()

    def pending(self, names: Sequence[str]) -> list[Task]:
        """The tasks among `names` still running."""
        return [t for n in names if (t := self.tasks.get(n)) is not None and not t.done]

    def wait(self, names: Sequence[str]) -> None:
        """Block until the tasks among `names` are done (failed ones included)."""
        for name in names:
            task = self.tasks.get(name)
            if task is not None:
                task._done.wait()

    def failure(self, name: str) -> str | None:
        """Why task `name` failed, or None (not started, running or done well)."""
        task = self.tasks.get(name)
        if task is None or not task.done or task._error is None:
            return None
        return f"{WHAT.get(name, name)} failed: {task._error}"


class BackgroundEmbedder:
    """An `Embedder` whose model loads on a background thread; `embed` waits for it.

    `name`, `dim`, `default_tau_s` and `default_tau_match` are known before the model
    loads (they are the bundled model's class attributes), so maps can be created and
    opened at once, and search hits carry their calibrated `match` flag.

    Args:
        task: the background task returning the real embedder.
        model: the real embedder's class (or any object with those four attributes).
    """

    def __init__(self, task: Task, model: Any) -> None:
        self.task = task
        self.name: str = model.name
        self.dim: int = model.dim
        self.default_tau_s: float = model.default_tau_s
        self.default_tau_match: float = model.default_tau_match

    def embed(self, texts: Sequence[str]) -> np.ndarray:  # -> [N, dim]
        """Embed with the real model (waiting for it to load the first time).

        Raises:
            GLMapError: the model failed to load (the message says why).
        """
        try:
            real: Embedder = self.task.wait()
        except GLMapError:
            raise
        except Exception as exc:
            raise GLMapError(f"the text embedder failed to load: {exc}") from exc
        return real.embed(texts)


def load_embedder(kind: str, threads: int | None) -> Embedder:
    """The embedder `kind` ('minilm' or 'hashing'), with torch (if a model needed it)
    limited to `threads`; BLAS is limited by `threads.limited_threads`."""

    from glmap_tools.language import embed, minilm

    if kind == "hashing":
        return embed.HashingEmbedder()
    model = minilm.default_embedder()
    torch = sys.modules.get("torch")  # the bundled MiniLM runs on numpy: no torch import
    if threads is not None and torch is not None:
        torch.set_num_threads(threads)
    return model


def warm_kernels() -> float:
    """Run every numba kernel of the map, the renderer and the simulator once; seconds.

    Each kernel is compiled, or loaded from numba's cache when `.ci/setup` filled it.
    """
    start = time.perf_counter()
    warm_map_kernels()
    warm_halves_kernels()
    warm_layer_kernels()
    warm_view_and_sim_kernels()
    return time.perf_counter() - start


def warm_view_and_sim_kernels() -> None:
    """Run every kernel but the map's once: the renderer's (splatting, with depth) and the
    simulator's (the Dijkstra of every episode's success distance)."""
    from glmap_tools.app.views import warm_up
    from glmap_tools.sim import geodesic

    warm_up()
    geodesic.warm_up()


def warm_layer_kernels() -> None:
    """Run the map layers' own kernels once, as a frame's update calls them: the occupancy
    marks, the structure voxels' merge and `merge.combine`; and the walls a navigation step
    reads from the structure layer, its planner's marcher and its lines of sight."""
    from glmap_tools.gaussians.merge import combine
    from glmap_tools.gaussians.types import GaussianSet
    from glmap_tools.map.occupancy import DenseOccupancy, OccupancyGrid
    from glmap_tools.map.structure import StructureLayer
    from glmap_tools.nav.footprint import GoalMatch, in_clear_sight
    from glmap_tools.nav.planner import geodesic
    from glmap_tools.nav.wall_counts import structure_walls_kept

    points = np.array([[1.0, 0.0, 0.0], [1.0, 0.1, 0.5], [1.1, 0.0, 0.02]])
    OccupancyGrid(0.05).compute_update(np.zeros(2), points, 0.0, (0.1, 1.5))
    g = GaussianSet(points, np.tile(np.eye(3) * 1e-4, (3, 1, 1)), np.full((3, 3), 0.5),
                    np.full(3, 0.8), np.array([5, 6, 7]))  # fmt: skip
    layer = StructureLayer(0.05)
    layer.apply(layer.compute_update(g))
    layer.compute_update(g)
    combine(g, np.array([0, 0, 1]))
    window = DenseOccupancy(np.zeros((4, 4), np.int8), (0, 0), 0.05)
    structure_walls_kept(layer, 0.0, [(0.1, 1.5), (1.5, 2.0)], window)
    geodesic(np.ones((4, 4), bool), (1, 1), 0.05, np.full((4, 4), 0.5), band=0.2)
    in_clear_sight(GoalMatch(1, 1.0, 1, np.array([[2, 2]])), window, np.array([[0, 0]]))


def warm_wide_cloud_kernels() -> None:
    """Run the estimator's kernels for a cloud too wide for the sorted sweep's cell keys
    (~2 million radii along every axis): the candidate Gaussians apart and the hashed block
    grid's pair search (`_estimator_fast.grid_pairs`). Servers meet it rarely; the tests do,
    so `glmap-mcp --prepare` fills numba's cache with it too."""
    from glmap_tools.gaussians.estimator import GaussianEstimator

    rng = np.random.default_rng(0)
    blob = rng.normal(0.0, 0.01, (400, 3))
    colours = rng.uniform(0.0, 1.0, (800, 3)).astype(np.float32)
    GaussianEstimator().fit(np.concatenate([blob, blob + 40_000.0]), colours)


def warm_halves_kernels() -> None:
    """Run the estimator's two-thread kernels for frame-sized clouds once (`fit_fast`'s
    halves: the input scan, voxelising and voxel moments), on a small cloud. They call
    little else, so `glmap-mcp --prepare` compiles them beside the map's process."""
    from glmap_tools.gaussians import _estimator_numba as kernels
    from glmap_tools.gaussians import _estimator_voxels as voxels
    from glmap_tools.gaussians.config import EstimatorConfig
    from glmap_tools.gaussians.estimator import validate_cloud

    rng = np.random.default_rng(0)
    voxel = EstimatorConfig().voxel_size
    points, colors, lo = validate_cloud(
        rng.uniform(0.0, 0.3, (600, 3)), rng.uniform(0.0, 1.0, (600, 3)), voxel
    )
    voxels.scan_cloud_halves(points, colors)
    lo_cell = np.floor(lo / voxel).astype(np.int64)
    origin = (lo_cell - voxels.CELL_MARGIN).astype(np.float64) * voxel
    point_voxel, _, voxel_block, *_, split = voxels.voxelize_halves(points, voxel, lo_cell)
    kernels.voxel_moments_split(points, colors, point_voxel, len(voxel_block), origin, split)


def warm_map_kernels() -> float:
    """Run the map's kernels once (the estimator, its merge, fusion); seconds.

    Two views of a chair and a third from the first pose again: the chair's masked points
    are enough for merged Gaussians (the fit's pair sweep, capped union and cluster sums),
    and its second and third observations fuse with the unit (`remerge`).
    """
    from glmap_tools.geometry import backproject
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.map import GLMap, MapConfig

    start = time.perf_counter()
    boxes = synthetic.floor(2.0) + synthetic.chair(0.0, 0.0, object_id=1)
    texts = {1: ("chair", "a red chair")}
    glmap = GLMap(MapConfig(), embedder=HashingEmbedder())
    # The estimator first, most of the compile: `glmap-mcp --prepare` warms the layers'
    # kernels in its other process meanwhile, so the frames below find them compiled.
    frame, ids = synthetic.view(boxes, (0.0, -1.2, 1.1), (0.0, 0.0, 0.4), *WARM_VIEW)
    chair = backproject(frame.depth, frame.intrinsics, frame.pose, frame.rgb, ids == 1)
    glmap.estimator.fit(chair.points, chair.colors)
    for shift in (0.0, 0.05, 0.0):
        frame, ids = synthetic.view(boxes, (shift, -1.2, 1.1), (0.0, 0.0, 0.4), *WARM_VIEW)
        glmap.integrate(frame, synthetic.semantics(ids, texts))
    return time.perf_counter() - start
