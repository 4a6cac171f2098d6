"""Navigation errors: subclasses of the project's `GLMapError` hierarchy."""

from __future__ import annotations

from glmap_tools.errors import GLMapError, InvalidInputError


class OutsideMapError(InvalidInputError):
    """A position (agent or goal) lies outside the map window the planner works on."""


class UnreachableGoalError(GLMapError):
    """No path leads to the goal; `nearest_xy` is the closest point that can be reached.

    Attributes:
        goal_xy: (x, y) the caller asked for (m).
        nearest_xy: (x, y) of the reachable cell closest to the goal, or None when the agent
            itself has nowhere to go.
    """

    def __init__(
        self,
        message: str,
        goal_xy: tuple[float, float],
        nearest_xy: tuple[float, float] | None,
    ) -> None:
        super().__init__(message)
        self.goal_xy = goal_xy
        self.nearest_xy = nearest_xy
