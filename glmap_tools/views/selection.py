"""View selection (paper §3.2): the agent-height camera in free space that sees most of a unit.

Candidates sit on rings around the target, every `angle_step_deg`, at distances set from
the target's extent; each is kept only if its cell is seen-free and clear of obstacles by
the agent radius. The camera is at floor + camera height, facing the target, level unless
the target is low (then pitched down just enough, at most `max_pitch_deg`). Each kept
candidate is scored by the target's Gaussians whose means project into the image and pass
a depth test against the rest of the map rendered from that camera, each weighted by its
opacity and by how squarely it faces the camera (`visibility.py`). See design.md for the
details and the tie-break.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import GaussianSet
from glmap_tools.geometry import Intrinsics, Pose
from glmap_tools.views.candidates import (
    PLACEMENTS,
    Candidate,
    Placement,
    SelectionConfig,
    TargetExtent,
    framing_distance,
    make_candidates,
    target_extent,
)
from glmap_tools.views.common import RenderedView, check_intrinsics, view_intrinsics
from glmap_tools.views.targets import (
    instance_ids_of,
    map_gaussians,
    render_gaussians,
    scene_gaussians,
    structure_gaussians,
    unit_label,
    with_structure,
)
from glmap_tools.views.visibility import Scorer

if TYPE_CHECKING:
    from glmap_tools.map.glmap import GLMap

__all__ = [
    "Candidate",
    "NoFreeViewpointError",
    "SelectionConfig",
    "ViewChoice",
    "render_selected_view",
    "select_view",
]


class NoFreeViewpointError(InvalidInputError):
    """No candidate camera around the unit lies in seen-free space (with require_free=True)."""


@dataclass(frozen=True)
class ViewChoice:
    """The chosen view of a unit, and every candidate considered.

    Attributes:
        unit_id: the instance or region looked at.
        label: "instance 3 (chair)" or "region 9".
        pose: the chosen camera (world_from_camera).
        intrinsics: the camera the view is meant for.
        chosen: the winning candidate.
        placement: where the winner stands: "free" unless no candidate was seen-free.
        fallback: True when the winner is not in seen-free space (see `note`).
        note: a sentence on how the view was chosen, for people and agents.
        candidates: every candidate, scored or not, in (ring, bearing) order.
    """

    unit_id: int
    label: str
    pose: Pose
    intrinsics: Intrinsics
    chosen: Candidate
    placement: Placement
    fallback: bool
    note: str
    candidates: tuple[Candidate, ...]

    @property
    def score(self) -> float:
        """The winner's score."""
        assert self.chosen.score is not None
        return self.chosen.score

    @property
    def visible(self) -> float:
        """The winner's visible fraction of the target."""
        assert self.chosen.visible is not None
        return self.chosen.visible


def select_view(
    glmap: GLMap,
    unit_id: int,
    intrinsics: Intrinsics | None = None,
    *,
    config: SelectionConfig | None = None,
    require_free: bool = False,
) -> ViewChoice:
    """Choose the agent-height camera that sees most of an instance or region (paper §3.2).

    Args:
        glmap: the map (its occupancy layer decides where a camera may stand).
        unit_id: an instance or region id.
        intrinsics: the camera of the final view (its field of view and aspect set the
            framing distance and the pitch); default `view_intrinsics()` (320x240, 79 deg).
        config: selection settings.
        require_free: raise NoFreeViewpointError instead of falling back when no candidate
            is in seen-free space.

    Returns:
        The chosen view and every candidate. When no candidate is seen-free, the best
        "unobserved" candidate is used, else the best "blocked" one, with fallback=True.

    Raises:
        UnknownIdError: no such unit (with the closest id).
        InvalidInputError: a bad id or intrinsics; NoFreeViewpointError (a subclass) with
            require_free=True and no free candidate.
    """
    config = config or SelectionConfig()
    intrinsics = check_intrinsics(intrinsics) if intrinsics is not None else view_intrinsics()
    target = target_extent(glmap, unit_id)
    label = unit_label(glmap, unit_id)
    candidates = make_candidates(glmap, target, intrinsics, config)
    placement = next(p for p in PLACEMENTS if any(c.placement == p for c in candidates))
    if require_free and placement != "free":
        raise NoFreeViewpointError(
            f"no seen-free viewpoint within {config.max_distance} m of {label} is clear of "
            f"obstacles by {config.agent_radius} m; observe the space around it, or call "
            "without require_free to get the best fallback view."
        )
    scorer = _scoring_camera(intrinsics, config.score_width)
    occluders = _occluders(glmap, target, candidates, config)
    scored: list[Candidate] = []
    score_view = Scorer(target.gaussians)
    with _one_thread():
        for c in candidates:
            if c.placement == placement:
                seen = score_view(occluders, c.pose(), scorer, config.occlusion_margin)
                c = dataclasses.replace(
                    c, score=seen.score, visible=seen.visible, in_view=seen.in_view
                )
            scored.append(c)
    framing = framing_distance(target, intrinsics, config)
    chosen = _best([c for c in scored if c.score is not None], framing, config.near_tie)
    return ViewChoice(
        unit_id=int(unit_id),
        label=label,
        pose=chosen.pose(),
        intrinsics=intrinsics,
        chosen=chosen,
        placement=placement,
        fallback=placement != "free",
        note=_note(label, chosen, placement, sum(c.score is not None for c in scored)),
        candidates=tuple(scored),
    )


@contextlib.contextmanager
def _one_thread() -> Iterator[None]:
    """Run numba's parallel kernels on one thread in this thread, then restore the count.

    The scoring renders are tiny (128 px wide, a cropped map): with two threads on a busy
    2-core machine the kernels' start-up and joins cost 2-4x the work itself (measured
    with `python -m glmap_tools.bench views`). numba's thread count is per calling thread.
    """
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


def _scoring_camera(intrinsics: Intrinsics, width: int) -> Intrinsics:
    """The final camera, shrunk to `width` pixels wide (same field of view and aspect)."""
    height = min(max(int(round(width * intrinsics.height / intrinsics.width)), 1), 2048)
    return intrinsics.scaled(width, height)


def _occluders(
    glmap: GLMap, target: TargetExtent, candidates: list[Candidate], config: SelectionConfig
) -> GaussianSet:
    """The rest of the map's Gaussians that can stand between a candidate and the target:
    the other instances and the structure background layer (walls, floor).

    Only Gaussians within the farthest candidate's distance (plus the target's radius) of
    the target's centre, horizontally, can; the others are dropped to keep scoring cheap.
    """
    reach = max(c.distance for c in candidates) + target.radius + 0.1

    def near(g: GaussianSet) -> np.ndarray:
        return np.hypot(*(g.means[:, :2].astype(np.float64) - target.center[:2]).T) <= reach

    cached = map_gaussians(glmap)
    keep = ~cached.mask_of(target.instance_ids) & near(cached.gaussians)
    background = structure_gaussians(glmap)
    return GaussianSet.concat([cached.gaussians.subset(keep), background.subset(near(background))])


def _best(scored: list[Candidate], framing: float, near_tie: float) -> Candidate:
    """Among candidates within `near_tie` of the best score, the one nearest the framing
    distance (by ratio); then the higher score, the nearer ring, the lower bearing index."""
    assert scored, "select_view always scores the candidates of one placement"
    best = max(c.score or 0.0 for c in scored)
    close = [c for c in scored if (c.score or 0.0) >= near_tie * best]
    return min(
        close,
        key=lambda c: (
            round(abs(math.log(c.distance / framing)), 9),
            -(c.score or 0.0),
            c.ring,
            c.bearing,
        ),
    )


def _note(label: str, chosen: Candidate, placement: Placement, n_scored: int) -> str:
    visible = chosen.visible or 0.0
    where = {
        "free": "in seen-free space",
        "unobserved": "FALLBACK: no seen-free viewpoint; this one is unobserved space",
        "blocked": "FALLBACK: every viewpoint is at or near an obstacle; this one is blocked",
    }[placement]
    return (
        f"{label}: chose 1 of {n_scored} candidate cameras ({where}), "
        f"{chosen.distance:.2f} m from its centre, {visible:.0%} of its Gaussians visible"
        + (" (the target is occluded from every candidate)" if visible == 0 else "")
        + "."
    )


def render_selected_view(
    glmap: GLMap,
    unit_id: int,
    intrinsics: Intrinsics | None = None,
    *,
    context: bool = False,
    config: SelectionConfig | None = None,
    require_free: bool = False,
    structure: bool | None = None,
) -> tuple[RenderedView, ViewChoice]:
    """Select a view of a unit (see `select_view`) and render it.

    Args:
        context: False draws only the unit's Gaussians; True the whole map from that camera.
        structure: also draw the structure background layer (walls, floor); None = as
            `context`.
    """
    choice = select_view(glmap, unit_id, intrinsics, config=config, require_free=require_free)
    ids = instance_ids_of(glmap, unit_id)
    cached = map_gaussians(glmap)
    structure = context if structure is None else structure
    if context:
        g = scene_gaussians(glmap, structure)
    else:
        g = with_structure(glmap, cached.gaussians.subset(cached.mask_of(ids)), structure)
    view = render_gaussians(g, choice.pose, choice.intrinsics, label=choice.label)
    return view, choice
