"""The official GLMap Gaussian estimator, timed beside ours: `bench estimator --official PATH`.

PATH is a clone of the paper's code (OFFICIAL_URL). Nothing of it is bundled here: its
`src/gaussian/estimator.py` is loaded from the clone, without its package's `__init__` (that
one imports the CUDA splatting renderer), and `GaussianEstimator(voxel_size).estimate(...)`
is timed on the same cloud in the same process as our fit, merge off (its default) and on.
The clock is the wall: the official code runs on one core, ours on numba's thread team
(`NUMBA_NUM_THREADS=1` compares the code alone).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools.errors import InvalidInputError

OFFICIAL_URL = "https://github.com/sx-zhang/GLMap"
PACKAGE = "glmap_official_gaussian"  # the clone's `gaussian` package, under a name of its own


@dataclass(frozen=True)
class OfficialTimes:
    """Median wall ms on one cloud, the rounds alternating between the two codes."""

    official: float  # estimate(points, colours): merge off, the official default
    official_merged: float  # estimate(points, colours, merge=True)
    ours: float  # our fit and merge
    ours_unmerged: float  # our fit, merge off
    official_gaussians: tuple[int, int]  # (merge off, merge on)
    official_range: tuple[float, float]  # fastest and slowest round of the default estimate()


def load_official_estimator(root: Path) -> type:
    """The `GaussianEstimator` class of the official code in the clone at `root`.

    Raises:
        InvalidInputError: `root` holds no `src/gaussian/estimator.py`, or it does not import.
    """
    src = Path(root).expanduser().resolve() / "src"
    package_dir = src / "gaussian"
    if not (package_dir / "estimator.py").is_file():
        raise InvalidInputError(
            f"--official {str(root)!r} holds no src/gaussian/estimator.py; pass the folder of a "
            f"clone of {OFFICIAL_URL} (git clone {OFFICIAL_URL} PATH)."
        )
    if PACKAGE not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            PACKAGE, package_dir / "__init__.py", submodule_search_locations=[str(package_dir)]
        )
        assert spec is not None
        sys.modules[PACKAGE] = importlib.util.module_from_spec(spec)  # __init__ not run
    if str(src) not in sys.path:
        sys.path.append(str(src))  # its `utils.coordinate_transforms`, found after ours
    try:
        module = importlib.import_module(f"{PACKAGE}.estimator")
    except ImportError as exc:
        raise InvalidInputError(
            f"--official {str(root)!r}: its src/gaussian/estimator.py does not import ({exc}); "
            f"it needs numpy and scipy, and the clone's src/utils."
        ) from exc
    return module.GaussianEstimator  # type: ignore[no-any-return]


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    """(wall ms, result) of one call."""
    t0 = time.perf_counter()
    result = fn()
    return (time.perf_counter() - t0) * 1e3, result


def official_times(
    official_class: type,
    ours: Callable[[], object],
    ours_unmerged: Callable[[], object],
    points: np.ndarray,
    colors: np.ndarray,
    voxel: float,
    rounds: int,
    ours_per_round: int = 9,
) -> OfficialTimes:
    """Each round: the official estimate with the merge off and on once each, then our fit
    merged and unmerged `ours_per_round` times each; medians over all rounds."""
    official = official_class(voxel_size=voxel)
    runs: dict[str, list[float]] = {"off": [], "off+merge": [], "ours": [], "ours unmerged": []}
    for _ in range(rounds):
        ms, off = _timed(lambda: official.estimate(points, colors))
        runs["off"].append(ms)
        ms, merged = _timed(lambda: official.estimate(points, colors, merge=True))
        runs["off+merge"].append(ms)
        for _ in range(ours_per_round):
            runs["ours"].append(_timed(ours)[0])
            runs["ours unmerged"].append(_timed(ours_unmerged)[0])
    counts = (off.num_gaussians, merged.num_gaussians)
    med = {k: float(np.median(v)) for k, v in runs.items()}
    spread = (min(runs["off"]), max(runs["off"]))
    return OfficialTimes(
        med["off"], med["off+merge"], med["ours"], med["ours unmerged"], counts, spread
    )
