"""`bench estimator --official PATH`: loading the paper's estimator from a clone.

The official code is not bundled and CI cannot fetch it, so the loader is held on a tree of
the clone's layout: a package `__init__` that fails to import (as the clone's does without
its CUDA renderer), a relative import, and the clone's absolute `utils` import.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from glmap_tools.bench.__main__ import main
from glmap_tools.bench._official import load_official_estimator, official_times
from glmap_tools.errors import InvalidInputError

ESTIMATOR = """
import numpy as np

from .data import GaussianData
from utils.coordinate_transforms import to_colmap


class GaussianEstimator:
    def __init__(self, voxel_size=0.015):
        self.voxel_size = voxel_size

    def estimate(self, positions, rgb_colors, merge=None):
        keys = np.unique(np.floor(to_colmap(positions) / self.voxel_size), axis=0)
        return GaussianData(keys[: len(keys) // 2] if merge else keys)
"""


def _clone(root):
    # as in the clone: src/utils has no __init__.py (a namespace package)
    (root / "src" / "gaussian").mkdir(parents=True)
    (root / "src" / "utils").mkdir()
    (root / "src" / "gaussian" / "__init__.py").write_text("raise ImportError('no CUDA here')\n")
    (root / "src" / "gaussian" / "estimator.py").write_text(ESTIMATOR)
    (root / "src" / "gaussian" / "data.py").write_text(
        textwrap.dedent(
            """
            class GaussianData:
                def __init__(self, data):
                    self.num_gaussians = len(data)
            """
        )
    )
    (root / "src" / "utils" / "coordinate_transforms.py").write_text(
        "def to_colmap(p):\n    return p[:, [1, 2, 0]] * [-1, -1, 1]\n"
    )
    return root


def test_a_folder_without_the_official_estimator_is_refused_before_any_timing(capsys, tmp_path):
    assert main(["estimator", "--no-cold", "--official", str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # refused before the synthetic frame is made and fitted
    assert err.startswith(f"bench estimator: error: --official '{tmp_path}' holds no ")
    assert "git clone https://github.com/sx-zhang/GLMap" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InvalidInputError, match="src/gaussian/estimator.py"):
        load_official_estimator(tmp_path / "missing")


def test_the_official_estimator_loads_from_a_clone_and_is_timed_beside_ours(tmp_path):
    official = load_official_estimator(_clone(tmp_path / "GLMap"))
    rng = np.random.default_rng(0)
    points = rng.uniform(0, 0.3, size=(3000, 3))
    colors = rng.uniform(0, 1, size=(3000, 3)).astype(np.float32)
    calls = []
    times = official_times(
        official,
        lambda: calls.append("merged"),
        lambda: calls.append("unmerged"),
        points,
        colors,
        0.03,
        rounds=2,
        ours_per_round=3,
    )
    assert calls == ["merged", "unmerged"] * 6
    cells = len(np.unique(np.floor(points[:, [1, 2, 0]] * [-1, -1, 1] / 0.03), axis=0))
    assert times.official_gaussians == (cells, cells // 2)
    assert times.official > 0 and times.official_merged > 0
    fastest, slowest = times.official_range
    assert 0 < fastest <= times.official <= slowest  # the median of two lies between them
