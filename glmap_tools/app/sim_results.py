"""Results of the simulator and navigation tools: sim_reset, sim_step, look_around,
value_map, frontiers, navigate_to, nav_step.

Each is a `Reply`: its text block is the JSON of the fields given, so an optional field
(a goal unit, the client's scores, the metrics of an ended episode) is left out rather
than sent as null. The episode's status (`SimStatus`) comes last where a tool adds its own
fields first: such a result lists `SimStatus` first among its bases, the fields of the
later bases coming first (pydantic orders fields base by base, the last base first).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from glmap_tools.app.results import Reply
from glmap_tools.language.sampling import usage_report

Heading = int  # whole degrees, counter-clockwise from +x


class SimStatus(Reply):
    """What the agent may know of its episode: goal, pose, steps, collisions; metrics once
    it ends."""

    task: str = Field(description="'objectnav' or 'instnav'")
    scene: int | str = Field(description="generated scene number, or a benchmark scene name")
    goal: str = Field(description="the goal category (objectnav) or description (instnav)")
    steps: int = Field(description="actions taken since sim_reset")
    max_steps: int = Field(description="the episode's step budget")
    position: tuple[float, float] = Field(description="agent (x, y), metres")
    heading_deg: float = Field(description="agent heading, degrees counter-clockwise from +x")
    camera_pose: list[list[float]] | None = Field(
        default=None, description="4x4 camera-to-world matrix (sim_reset, sim_step)"
    )
    collided: bool = Field(description="the last action bumped into something")
    collisions: int = Field(description="bumps since sim_reset")
    status: str = Field(
        description="'running', 'success', 'out of steps' or 'stopped, not at the goal'"
    )
    episode: str | None = Field(default=None, description="benchmark episode id, if any")
    success: bool | None = Field(default=None, description="once over: the stop counted")
    spl: float | None = Field(default=None, description="once over: success weighted by path")
    distance_to_goal: float | None = Field(
        default=None, description="once over: geodesic metres to the nearest goal"
    )
    path_length: float | None = Field(default=None, description="once over: metres walked")
    episode_outcome: str | None = Field(
        default=None, description="once over: the kind of ending (glmap_tools.sim.outcome)"
    )


class SamplingReport(Reply):
    """What the client's model (MCP sampling) cost this session so far."""

    sampling_calls: int = Field(description="requests sent")
    sampling_failed: int = Field(description="requests that failed or timed out")
    est_prompt_tokens: int = Field(description="estimated tokens asked")
    est_output_tokens: int = Field(description="estimated tokens answered")
    sampling_s: float = Field(description="seconds waited")
    fallbacks: int = Field(description="model parts that fell back")
    last_fallback: str | None = Field(default=None, description="what the last fallback said")


class SimResult(SimStatus):
    """sim_reset and sim_step: the episode's status, and what the frames added to the map."""

    session: str = Field(description="session handle (pass as `session` over stateless HTTP)")
    map_updates: list[str] = Field(description="one line per frame integrated")
    actions: list[str] = Field(description="the actions sim_step takes")
    llm: SamplingReport | None = Field(default=None, description="when the client's model ran")


class MapCounts(Reply):
    """Units in the map."""

    instances: int
    regions: int


class LookAroundResult(SimStatus):
    """look_around: the status after the full turn, and the map's size."""

    map: MapCounts


class Waypoint(Reply):
    """Where the policy heads next, and where that lies from the agent."""

    kind: str = Field(description="'goal', 'frontier', 'explore' or 'none'")
    xy: tuple[float, float] | None = Field(default=None, description="metres (not for 'none')")
    unit_id: int | None = Field(default=None, description="the matched unit, for 'goal'")
    score: float = Field(description="the unit's score (goal) or the value at the waypoint")
    distance_m: float | None = Field(default=None, description="straight-line from the agent")
    bearing_deg: float | None = Field(
        default=None, description="from the agent's heading, + = to its left"
    )
    reason: str = Field(description="why this waypoint")


class HeldScores(Reply):
    """The client's f_S of the episode's goal, as held now."""

    scores: list[tuple[int, str, float]] = Field(description="[unit id, kind, s]")
    priors: list[tuple[str, float, list[int]]] = Field(
        description="[region kind, s, ids of the regions it names]"
    )
    followed: list[str] | None = Field(
        default=None, description="'12->7': a fused unit's score moved to the unit it became"
    )


class ValueMapResult(Reply):
    """value_map: the value map's best cells and units, and the waypoint it gives."""

    goal: str
    units: Literal["both", "instances", "regions"]
    agent: tuple[float, float, Heading] = Field(description="x, y (m), heading (deg)")
    waypoint: Waypoint
    matched_unit: int | None = Field(description="the unit taken for the goal, if any")
    top_cells: list[tuple[float, float, float]] = Field(description="[x, y, value], best first")
    top_units: list[tuple[int, str, float, str]] = Field(
        description="[id, kind, s_u, by]; by: 'client', 'prior' or 'scorer'"
    )
    evidence: str = Field(description="'units', 'region hint' or 'none' (a frontier decides)")
    frontiers: int = Field(description="reachable frontiers")
    client: HeldScores | None = Field(default=None, description="the client's scores, if any")


class Frontier(Reply):
    """One reachable frontier."""

    xy: tuple[float, float] = Field(description="metres")
    cells: int = Field(description="frontier cells")
    path_m: float | None = Field(description="planned path length; null: no path")
    distance_m: float = Field(description="straight-line from the agent")
    bearing_deg: float = Field(description="from the agent's heading, + = to its left")


class FrontiersResult(Reply):
    """frontiers: the reachable frontiers, nearest first."""

    agent: tuple[float, float] = Field(description="agent (x, y), metres")
    frontiers: list[Frontier]
    total: int = Field(description="frontiers found (more than listed when cut at top_k)")


class Walk(Reply):
    """How a walk to a point or a unit went (navigate_to)."""

    outcome: str = Field(
        description="'reached', 'reached the nearest reachable point', 'blocked', "
        "'step budget' or 'episode over'"
    )
    walk_steps: int
    walked_m: float = Field(description="path length walked")
    walk_collisions: int
    planned_m: float | None = Field(description="the first plan's length; null: no path")
    aim_xy: tuple[float, float] | None = Field(description="the point last aimed at")
    remaining_m: float | None = Field(description="planned metres left; null: no path")
    reason: str
    unit_id: int | None = Field(default=None, description="for a unit target")
    unit_distance_m: float | None = Field(default=None, description="for a unit target")
    in_sight: bool | None = Field(default=None, description="for a unit: in clear sight")
    would_succeed: bool | None = Field(
        default=None, description="for a unit: a stop here would count"
    )
    blocked_by: str | None = Field(default=None, description="when short: what, and what to try")


class UnitScore(Reply):
    """A unit's score for the episode's goal."""

    goal_score: float | None = Field(default=None, description="for a unit target: its s_u")
    score_by: str | None = Field(default=None, description="'client', 'prior' or 'scorer'")


class NavigateResult(SimStatus, UnitScore, Walk):
    """navigate_to: the walk, the unit's score for a unit target, then the status."""


class StepTaken(Reply):
    """One action the policy took."""

    step: int
    action: str
    position: tuple[float, float] = Field(description="agent (x, y) after it, metres")
    heading_deg: Heading


class Decision(StepTaken):
    """One action and the waypoint it followed."""

    waypoint: Waypoint


class ClientScoreCounts(Reply):
    """How many of the client's scores the policy holds."""

    units: int
    priors: int


class GoalUnit(Reply):
    """The unit the policy took for the goal, and whether stopping here would count."""

    id: int
    score: float
    unit_distance_m: float
    in_sight: bool
    would_succeed: bool


class NavSteps(Reply):
    """What nav_step did (its own fields, before the status)."""

    outcome: Literal["actions done", "policy would stop here", "episode over"]
    actions: dict[str, int] = Field(description="count of each action taken")
    walked_m: float = Field(description="path length walked")
    new_collisions: int
    waypoint: Waypoint | None = Field(description="the last decision's; null: none taken")
    client_scores: ClientScoreCounts | None = Field(default=None)
    goal_unit: GoalUnit | None = Field(default=None, description="while the episode runs")
    decisions: list[Decision] | None = Field(default=None, description="with details")
    last: list[StepTaken] | None = Field(default=None, description="the last 3 steps")


class NavStepResult(SimStatus, NavSteps):
    """nav_step: its steps, then the status."""


def sampling_report() -> SamplingReport | None:
    """The running tool call's session's sampling figures, or None when nothing was sampled."""
    report = usage_report()
    return SamplingReport.model_validate(report) if report else None
