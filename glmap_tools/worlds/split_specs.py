"""How each benchmark split is generated: its scenes' generator options and its goal mix.

`SPLIT_SPECS` names every built-in split; `make_layout` builds a split's scene and
`goal_weights` gives the chance of each goal of a scene to be an episode's goal (uniform for
the regression splits tune/bench, weighted towards HM3D's categories and same-category
instances for the house splits). `splits.py` draws the episodes and writes the files.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from glmap_tools.sim.layout import Layout
from glmap_tools.worlds.clutter import GOAL_CATEGORIES
from glmap_tools.worlds.generator import generate_apartment


@dataclass(frozen=True)
class SplitSpec:
    """How one split is generated.

    Attributes:
        house: houses (`generate_house`, rooms drawn from the seed) instead of apartments.
        perception: the perception the split is meant to be played with by default
            ("gt" or "detector"; written to `split.json`, read by `split_perception`).
        hm3d_share: ObjectNav: the chance that an episode's goal is one of HM3D's six
            categories (`clutter.GOAL_CATEGORIES`) present in the scene; None: every
            category equally likely (the regression splits).
        multi_share: InstNav: the chance that the target is one of at least two objects of
            its category in the scene; None: every describable object equally likely.
        seeable_only: goals only among objects the camera can be expected to recognise
            (`episodes.unseeable`).
    """

    name: str
    seeds: tuple[int, ...]
    episodes_per_scene: int  # per task
    area_scale: float = 1.3
    hallway: bool = True
    house: bool = False
    perception: str = "gt"
    hm3d_share: float | None = None
    multi_share: float | None = None
    seeable_only: bool = False

    def n_rooms(self, seed: int) -> int | None:
        if self.house:
            return None  # 7-11 furnished rooms drawn from the seed, plus the hallway
        return 6 + seed % 2  # six or seven furnished rooms, plus the hallway


def _house_split(name: str, seeds: range) -> SplitSpec:
    return SplitSpec(
        name, tuple(seeds), 20, area_scale=1.0, house=True, perception="detector",
        hm3d_share=0.6, multi_share=0.8, seeable_only=True,
    )  # fmt: skip


SPLIT_SPECS = {
    "tune": SplitSpec("tune", tuple(range(1000, 1004)), 25),
    "bench": SplitSpec("bench", tuple(range(2000, 2012)), 20),
    "house-tune": _house_split("house-tune", range(3000, 3004)),
    "house-bench": _house_split("house-bench", range(4000, 4012)),
}


def make_layout(spec: SplitSpec, seed: int) -> Layout:
    """The split's apartment or house for `seed` (what `layout.json` holds)."""
    if spec.house:
        return generate_apartment(seed, area_scale=spec.area_scale, house=True)
    return generate_apartment(
        seed, n_rooms=spec.n_rooms(seed), area_scale=spec.area_scale, hallway=spec.hallway
    )


def goal_weights(layout: Layout, task: str, pool: Any, spec: SplitSpec) -> np.ndarray | None:
    """The chance of each goal of `pool` to be an episode's goal under `spec`'s mix, or None
    for a uniform draw (the regression splits draw exactly as they always did).

    ObjectNav with `hm3d_share`: HM3D's categories share that much, the others the rest;
    InstNav with `multi_share`: targets with another object of their category share that
    much, the others the rest (each group uniform; an empty group gives its share away).
    """
    share = spec.hm3d_share if task == "objectnav" else spec.multi_share
    if share is None:
        return None
    counts: dict[str, int] = {}
    for o in layout.objects:
        counts[o.category] = counts.get(o.category, 0) + 1
    if task == "objectnav":
        first = np.array([text in GOAL_CATEGORIES for text, _, _ in pool])
    else:
        first = np.array([counts[layout.object(ids[0]).category] >= 2 for _, ids, _ in pool])
    if first.all() or not first.any():
        return np.full(len(pool), 1.0 / len(pool))
    return np.where(first, share / first.sum(), (1.0 - share) / (~first).sum())
