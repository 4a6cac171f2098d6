"""`NavConfig`: every tunable of the navigation core in one place."""

from __future__ import annotations

import math
from dataclasses import dataclass

from glmap_tools.errors import InvalidInputError, did_you_mean

# Calibrated on the tune split (scene seeds 1000-1003), see nav/design.md: the score s_u at
# which an instance counts as the goal, per task (category names vs full descriptions).
STOP_THRESHOLDS = {"objectnav": 0.56, "instnav": 0.75}
# ObjectNav goals are category names: a match must also name the goal better than any other
# label in the map (margin in cosine; None = no such check). See nav/design.md.
CATEGORY_MARGINS: dict[str, float | None] = {"objectnav": 0.0, "instnav": None}
# With the margin check, a lower score suffices: tune layout texts of every goal category
# (picture: cos 0.49-0.52, below the 0.65 of STOP_THRESHOLDS) are then all matched and no
# other category is (cos >= 0.45 and margin >= 0: 100 % precision and recall on s00-s03).
CATEGORY_STOP_THRESHOLD = 0.31
# A unit the agent's 0.88 m camera cannot be expected to recognise is no goal: the rule by
# which `glmap sim episodes` refuses goals (sim.episodes.MIN_GOAL_SIZE / MAX_GOAL_BOTTOM; a
# test holds them equal). Metres: the largest side of the unit, the height of its bottom
# above the floor (a ceiling light 2.7 m up, a picture's frame above a wardrobe).
GOAL_MIN_SIZE = 0.15
GOAL_MAX_BOTTOM = 1.8
# Scores this close are a tie (identical texts: four "lamp" units at 0.923).
SCORE_TIE = 1e-6
POLICIES = ("glmap", "glmap-instance", "glmap-region", "egocentric", "frontier")
# The agent's discrete actions; a name's index is the simulator's action id (Habitat's order).
ACTIONS = ("stop", "move_forward", "turn_left", "turn_right")
UNIT_MASSES = ("unit", "cells")


@dataclass(frozen=True)
class NavConfig:
    """Settings of the navigation core (see nav/design.md for how each number was chosen).

    Attributes:
        agent_radius: metres; the simulator keeps the agent's centre this far from every
            blocked cell's edge (`agent_radius + cell/2` from its centre: the body radius).
        success_radius: metres; an episode succeeds when the agent stops this close to the goal.
        forward_step: metres per move_forward.
        turn_angle_deg: degrees per turn_left / turn_right.
        value_sigma: bandwidth sigma (m) of the Gaussian kernel K_sigma of Eq. 7.
        stop_threshold: score s_u in [0, 1] at which an instance matches the goal.
        min_observations: frames that must have observed a matching instance.
        category_margin: when set, a matching instance's cosine with the goal must exceed
            its cosine with every other label of the map by this much (category goals).
        category_threshold: the score s_u that suffices when the margin check applies.
        stop_distance: metres from the matched unit's cells where the agent stops (kept below
            success_radius so footprint error in the map does not cost the episode).
        stop_in_sight: stop only where the line to the matched unit's nearest cell crosses
            no mapped wall, when such a reachable cell exists within stop_distance (the
            success rule asks for a clear line to the footprint). Walls are the obstacle
            cells the structure layer holds (not furniture: a chair's seat does not hide
            the chair).
        min_frontier_size: frontier clusters with fewer cells are dropped.
        window_margin: metres of unknown space kept around the known map for planning.
        optimistic: whether plans may cross unknown cells (frontier exploration does).
        stuck_steps: steps without progress after which the waypoint is given up.
        plan_stride: the FMM that finds frontiers and waypoints works on cells this many map
            cells wide (the cost-to-go the agent follows is on map cells).
        initial_spin: turn_left steps taken first, to look around (12 x 30 deg = a full turn).
        clearance: metres of clearance (cell centre to the nearest obstacle cell centre)
            below which crossing a cell costs more (nav.motion).
        clearance_cost: extra cost per metre at the body radius (quadratic in the shortfall).
        safety_margin: metres beyond the body radius a forward step keeps from obstacles
            when it can (map cells are a cell off the true surface either way).
        turn_cost: cost-to-go metres one turn is worth when choosing a heading (nav.motion).
        min_instance_score, min_region_score: an instance / region enters Eq. 7 only with
            s_u at or above this (0 = every unit, Eq. 7 as written); with no unit left the
            waypoint is the nearest frontier. The evidence gate: with the offline scorer most
            scores are weak and their argmax points nowhere (nav/design.md "Evidence gate").
        region_hint: when no unit passes the evidence gate, the regions scoring at least
            this share of the best region's score enter Eq. 7 (`nav.value.evidence_scores`:
            region texts that suggest the goal guide exploration before the nearest
            frontier); 0 = none, the value map stays empty below the gate.
        unit_mass: how a unit's score s_u enters Eq. 7: 'unit' (default: s_u / |cells| on each
            cell, so every unit carries the mass s_u, as the single delta at p_u of Eq. 7 does)
            or 'cells' (s_u on each of its cells; situated localisation uses it).
        footprint_core: share of a matched instance's points whose densest cells stand for
            its footprint in the stop and approach rules (`nav.value.unit_core_cells`; 1 =
            every cell the index grid gives it).
    """

    agent_radius: float = 0.18
    success_radius: float = 1.0
    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    value_sigma: float = 0.5
    stop_threshold: float = 0.56
    min_observations: int = 2
    category_margin: float | None = None
    category_threshold: float = CATEGORY_STOP_THRESHOLD
    stop_distance: float = 0.75
    stop_in_sight: bool = True
    min_frontier_size: int = 5
    window_margin: float = 1.0
    optimistic: bool = True
    stuck_steps: int = 12
    plan_stride: int = 2
    initial_spin: int = 12
    clearance: float = 0.45
    clearance_cost: float = 3.0
    safety_margin: float = 0.05
    turn_cost: float = 0.02
    min_instance_score: float = 0.5
    min_region_score: float = 0.3
    region_hint: float = 0.0
    unit_mass: str = "unit"
    footprint_core: float = 0.8

    def __post_init__(self) -> None:
        positive = (
            "agent_radius",
            "success_radius",
            "forward_step",
            "turn_angle_deg",
            "value_sigma",
            "stop_distance",
            "clearance",
        )
        for name in positive:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InvalidInputError(f"NavConfig.{name}={value!r} must be a positive number.")
        if not 0.0 <= self.category_threshold <= 1.0:
            raise InvalidInputError(
                f"NavConfig.category_threshold={self.category_threshold!r} must be a score "
                "in [0, 1]."
            )
        if not 0.0 <= self.stop_threshold <= 1.0:
            raise InvalidInputError(
                f"NavConfig.stop_threshold={self.stop_threshold!r} must be a score in [0, 1]."
            )
        if self.stop_distance > self.success_radius:
            raise InvalidInputError(
                f"NavConfig.stop_distance={self.stop_distance} must not exceed "
                f"success_radius={self.success_radius}; the agent would stop too far away."
            )
        for name in (
            "min_observations",
            "min_frontier_size",
            "stuck_steps",
            "plan_stride",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise InvalidInputError(f"NavConfig.{name}={value!r} must be an integer >= 1.")
        if not (isinstance(self.initial_spin, int) and self.initial_spin >= 0):
            raise InvalidInputError(
                f"NavConfig.initial_spin={self.initial_spin!r} must be an integer >= 0."
            )
        if self.category_margin is not None and not math.isfinite(self.category_margin):
            raise InvalidInputError(
                f"NavConfig.category_margin={self.category_margin!r} must be finite or None."
            )
        for name in ("optimistic", "stop_in_sight"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInputError(
                    f"NavConfig.{name}={getattr(self, name)!r} must be true or false."
                )
        if self.unit_mass not in UNIT_MASSES:
            raise InvalidInputError(
                f"NavConfig.unit_mass={self.unit_mass!r} is not one of "
                f"{list(UNIT_MASSES)}.{did_you_mean(self.unit_mass, UNIT_MASSES)}"
            )
        for name in ("min_instance_score", "min_region_score"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 <= value <= 1.0):
                raise InvalidInputError(
                    f"NavConfig.{name}={value!r} must be a score in [0, 1] (0 = keep every unit)."
                )
        if not (isinstance(self.region_hint, int | float) and 0.0 <= self.region_hint <= 1.0):
            raise InvalidInputError(
                f"NavConfig.region_hint={self.region_hint!r} must be a share in [0, 1] "
                "(0 = no region hint below the evidence gate)."
            )
        for name in ("clearance_cost", "safety_margin", "turn_cost"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise InvalidInputError(f"NavConfig.{name}={value!r} must be a number >= 0.")
        fc = self.footprint_core
        if not (isinstance(fc, int | float) and 0.0 < fc <= 1.0):
            raise InvalidInputError(
                f"NavConfig.footprint_core={fc!r} must be a share in (0, 1] (1 = every cell)."
            )
        if self.window_margin < 0:
            raise InvalidInputError(f"NavConfig.window_margin={self.window_margin!r} must be >= 0.")

    @classmethod
    def for_task(cls, task: str, **overrides: object) -> NavConfig:
        """The defaults with the stop threshold calibrated for `task` ('objectnav'|'instnav')."""
        if task not in STOP_THRESHOLDS:
            raise InvalidInputError(
                f"unknown task {task!r}.{did_you_mean(task, STOP_THRESHOLDS)} "
                f"Choose from {sorted(STOP_THRESHOLDS)}."
            )
        values: dict[str, object] = {
            "stop_threshold": STOP_THRESHOLDS[task],
            "category_margin": CATEGORY_MARGINS[task],
            **overrides,
        }
        return cls(**values)  # type: ignore[arg-type]

    @property
    def turn_angle(self) -> float:
        """Radians per turn."""
        return math.radians(self.turn_angle_deg)


def check_policy(policy: str) -> str:
    """Return `policy` or raise InvalidInputError naming the known ones."""
    if policy not in POLICIES:
        raise InvalidInputError(
            f"unknown navigation policy {policy!r}.{did_you_mean(policy, POLICIES)} "
            f"Choose from {list(POLICIES)}."
        )
    return policy
