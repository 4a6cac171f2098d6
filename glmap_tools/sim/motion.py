"""The agent's body: planar state, discrete actions and collision against the navigable grid."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from glmap_tools.geometry import Pose
from glmap_tools.nav.config import ACTIONS
from glmap_tools.sim.navgrid import NavGrid

COLLISION_STEP = 0.025  # metres between collision checks along a forward move


class Action(IntEnum):
    """The env's action ids: each name's index in `nav.ACTIONS` (Habitat's order)."""

    STOP = ACTIONS.index("stop")
    MOVE_FORWARD = ACTIONS.index("move_forward")
    TURN_LEFT = ACTIONS.index("turn_left")
    TURN_RIGHT = ACTIONS.index("turn_right")


@dataclass(frozen=True)
class AgentState:
    """Planar position (metres) and heading (radians from +x, counter-clockwise)."""

    x: float
    y: float
    heading: float

    @property
    def xy(self) -> np.ndarray:  # [2]
        return np.array([self.x, self.y])

    def pose(self, camera_height: float) -> Pose:
        """The camera's world_from_camera pose (level, looking along the heading)."""
        return Pose.from_position_heading(self.x, self.y, camera_height, self.heading)


@dataclass(frozen=True)
class MotionConfig:
    """Step sizes of the discrete actions."""

    forward_step: float = 0.25  # metres
    turn_angle: float = math.radians(30.0)  # radians


def wrap_angle(angle: float) -> float:
    """Angle in [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def move_forward(grid: NavGrid, state: AgentState, distance: float) -> tuple[AgentState, bool]:
    """Walk `distance` metres along the heading, stopping before the first blocked point.

    Points are checked every `COLLISION_STEP` metres; the agent ends at the last free one.

    Returns:
        (new state, whether a collision cut the move short).
    """
    dx, dy = math.cos(state.heading), math.sin(state.heading)
    n = max(1, math.ceil(distance / COLLISION_STEP - 1e-9))
    last = 0.0
    for i in range(1, n + 1):
        t = distance * i / n
        if not grid.navigable_at(state.x + t * dx, state.y + t * dy):
            if last == 0.0:
                return state, True
            return AgentState(state.x + last * dx, state.y + last * dy, state.heading), True
        last = t
    return AgentState(state.x + distance * dx, state.y + distance * dy, state.heading), False


def apply_action(
    grid: NavGrid, state: AgentState, action: int, config: MotionConfig
) -> tuple[AgentState, bool]:
    """The state after one action, and whether it collided (STOP leaves the state as is)."""
    if action == Action.MOVE_FORWARD:
        return move_forward(grid, state, config.forward_step)
    if action == Action.TURN_LEFT:
        return AgentState(state.x, state.y, wrap_angle(state.heading + config.turn_angle)), False
    if action == Action.TURN_RIGHT:
        return AgentState(state.x, state.y, wrap_angle(state.heading - config.turn_angle)), False
    return state, False
