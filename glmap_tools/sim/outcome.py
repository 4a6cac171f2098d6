"""How a navigation episode ended: success, or which kind of failure (the failure taxonomy).

Kinds, first that applies:

- `success`;
- `stopped short`: stopped within `SHORT_M` geodesic metres of a cell that would have counted;
- `stopped at another instance`: stopped farther away, within reach of an object of the goal's
  category that is not the goal (InstNav: the right category, not the described instance);
- `stopped at a false positive`: stopped farther away, at no object of the goal's category (the
  agent took something else for the goal, or gave up where no goal was);
- out of steps: `goal never seen` (no goal object was ever in view with as many pixels as a
  detection needs), `goal seen, not recognised` (in view, never perceived with the goal's
  category), or `timeout` (recognised, never reached).
"""

from __future__ import annotations

OUTCOMES = (
    "success",
    "stopped short",
    "stopped at another instance",
    "stopped at a false positive",
    "goal never seen",
    "goal seen, not recognised",
    "timeout",
)
SHORT_M = 1.0  # geodesic metres from the nearest goal cell


def episode_outcome(
    success: bool,
    truncated: bool,
    distance_to_goal: float,
    goal_seen: bool,
    goal_recognised: bool,
    at_goal_category: bool = False,
) -> str:
    """The kind of `OUTCOMES` an ended episode falls in (see the module docstring);
    `at_goal_category`: the stop was within reach of a non-goal object of the goal's category."""
    if success:
        return "success"
    if not truncated:
        if distance_to_goal <= SHORT_M:
            return "stopped short"
        return "stopped at another instance" if at_goal_category else "stopped at a false positive"
    if not goal_seen:
        return "goal never seen"
    if not goal_recognised:
        return "goal seen, not recognised"
    return "timeout"
