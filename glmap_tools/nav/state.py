"""`NavState`: a policy's memory over one episode (read and written by `decide`, fed by the
episode step's `remember`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from glmap_tools.nav.choose import GoalProgress
from glmap_tools.nav.egocentric import EgocentricValueMap
from glmap_tools.nav.scorers import Scorer
from glmap_tools.nav.waypoint import Waypoint


@dataclass
class NavState:
    """Per-episode memory of a policy: the egocentric map, given-up waypoints, bump marks.

    Attributes:
        egocentric: the VLFM-like accumulator (fed by `nav.episode.remember`, read by the
            policy 'egocentric').
        avoid: (x, y) of waypoints given up (stuck, or reached without clearing them).
        rejected_units: matched instances given up (no way to reach them).
        blocked: (i, j) cells where a forward move was stopped (obstacles the map missed);
            they stay obstacles for the episode (`nav.motion.bump_cells`).
        last_waypoint: the previous step's waypoint.
        turns_in_place: turns in a row without moving, after the initial look around.
        steps: decisions taken.
        missed: instance id -> frames that looked at it without seeing it (glmap policies,
            `verify.missed_in_view`).
        goal_progress: how the agent closes in on its match (`choose.goal_progress`).
    """

    egocentric: EgocentricValueMap | None = None
    avoid: list[tuple[float, float]] = field(default_factory=list)
    rejected_units: set[int] = field(default_factory=set)
    blocked: set[tuple[int, int]] = field(default_factory=set)
    last_waypoint: Waypoint | None = None
    last_action: str | None = None
    last_xy: tuple[float, float] | None = None
    last_heading: float = 0.0
    best_distance: float = math.inf
    since_progress: int = 0
    turns_in_place: int = 0
    steps: int = 0
    scorer: Scorer | None = None
    missed: dict[int, int] = field(default_factory=dict)
    goal_progress: GoalProgress = field(default_factory=GoalProgress)
