"""Navigation with a GLMap (paper 3.2): frontiers, the Eq. 7 value map, the waypoint rule,
an FMM planner with its discrete next action, goal scorers f_S and the per-step policies.

Pure numpy/scipy/numba: no MCP, no model library (scorers receive an embedder).
"""

from glmap_tools.nav.config import ACTIONS, POLICIES, STOP_THRESHOLDS, NavConfig
from glmap_tools.nav.egocentric import EgocentricValueMap
from glmap_tools.nav.errors import OutsideMapError, UnreachableGoalError
from glmap_tools.nav.footprint import GoalMatch
from glmap_tools.nav.frontiers import Frontier, frontiers
from glmap_tools.nav.grid import Window, inflate, plannable, traversable
from glmap_tools.nav.motion import bump_cells, clearance, drive
from glmap_tools.nav.planner import (
    DIJKSTRA8_MAX_RATIO,
    DistanceField,
    Plan,
    distance_field,
    geodesic,
    plan,
    reference_geodesic,
)
from glmap_tools.nav.policy import NavDecision, decide
from glmap_tools.nav.scorers import EmbeddingScorer, Scorer, UnitText, map_units
from glmap_tools.nav.state import NavState
from glmap_tools.nav.value import (
    ValueMap,
    value_map,
    value_map_from_scores,
    value_map_reference,
)
from glmap_tools.nav.waypoint import Waypoint, choose_waypoint

__all__ = [
    "ACTIONS",
    "DIJKSTRA8_MAX_RATIO",
    "POLICIES",
    "STOP_THRESHOLDS",
    "DistanceField",
    "EgocentricValueMap",
    "EmbeddingScorer",
    "Frontier",
    "GoalMatch",
    "NavConfig",
    "NavDecision",
    "NavState",
    "OutsideMapError",
    "Plan",
    "Scorer",
    "UnitText",
    "UnreachableGoalError",
    "Waypoint",
    "ValueMap",
    "Window",
    "bump_cells",
    "choose_waypoint",
    "clearance",
    "decide",
    "distance_field",
    "drive",
    "frontiers",
    "geodesic",
    "inflate",
    "map_units",
    "plan",
    "plannable",
    "reference_geodesic",
    "traversable",
    "value_map",
    "value_map_from_scores",
    "value_map_reference",
]
