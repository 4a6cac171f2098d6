"""Reference agents for the navigation envs: an oracle shortest-path agent and a random one.

The oracle plans over the agent's own action lattice (positions reached by 0.25 m steps,
headings in 30 degree turns from the start) with weighted A* (the geodesic distance field to
the goal cells, in steps, times `HEURISTIC_WEIGHT`, as the heuristic; ties go deeper), and
stops once it stands in a goal cell. Plain A* ran out of expansions on the benchmark's long
episodes (turns cost a step the heuristic does not see) and fell back to greedy steps. It
reads the env's ground truth (`env.grid`, `env.goal_field`, `env.state`) and never looks at
observations.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from glmap_tools.sim.env import NavEnv
from glmap_tools.sim.motion import Action, AgentState, apply_action

MAX_EXPANSIONS = 60_000
HEURISTIC_WEIGHT = 1.5  # weighted A*: paths at most 1.5x the lattice optimum, found far faster
POSITION_KEY = 0.02  # metres: states closer than this (same heading) count as one


class OracleAgent:
    """Walks the shortest action sequence to the goal and stops (uses ground truth)."""

    def __init__(self, env: NavEnv) -> None:
        self.env = env
        self._plan: list[int] = []
        self._expected: AgentState | None = None

    def reset(self) -> None:
        self._plan, self._expected = [], None

    def _in_goal(self, state: AgentState) -> bool:
        return self.env.distance_to_goal(state) == 0.0

    def _plan_actions(self, start: AgentState) -> list[int]:
        env = self.env
        step = env.motion.forward_step

        def h(s: AgentState) -> float:
            d = env.distance_to_goal(s)
            return d / step if math.isfinite(d) else math.inf

        def key(s: AgentState) -> tuple[int, int, int]:
            k = round(
                math.remainder(s.heading - start.heading, 2 * math.pi) / env.motion.turn_angle
            )
            return (round(s.x / POSITION_KEY), round(s.y / POSITION_KEY), k)

        counter = 0
        # Ties in f go to the deeper state (-g): on the long plateaus of equal f that turns
        # make, this walks on instead of widening the search.
        frontier: list[tuple[float, int, int, int, AgentState, list[int]]] = [
            (HEURISTIC_WEIGHT * h(start), 0, counter, 0, start, [])
        ]
        seen = {key(start)}
        while frontier and counter < MAX_EXPANSIONS:
            _, _, _, g, state, actions = heapq.heappop(frontier)
            if self._in_goal(state):
                return [*actions, int(Action.STOP)]
            for action in (Action.MOVE_FORWARD, Action.TURN_LEFT, Action.TURN_RIGHT):
                nxt, collided = apply_action(env.grid, state, int(action), env.motion)
                if collided:
                    continue
                k = key(nxt)
                if k in seen:
                    continue
                seen.add(k)
                cost = h(nxt)
                if not math.isfinite(cost):
                    continue
                counter += 1
                heapq.heappush(
                    frontier,
                    (
                        g + 1 + HEURISTIC_WEIGHT * cost,
                        -(g + 1),
                        counter,
                        g + 1,
                        nxt,
                        [*actions, int(action)],
                    ),
                )
        return []

    def _greedy(self) -> int:
        env = self.env
        state = env.state
        if self._in_goal(state):
            return int(Action.STOP)
        best_turns, best_value = 0, env.distance_to_goal(state)
        for turns in range(-5, 7):
            heading = state.heading + turns * env.motion.turn_angle
            probe, collided = apply_action(
                env.grid,
                AgentState(state.x, state.y, heading),
                int(Action.MOVE_FORWARD),
                env.motion,
            )
            value = env.distance_to_goal(probe)
            if not collided and value < best_value - 1e-9:
                best_turns, best_value = turns, value
        if best_turns == 0:
            return int(Action.MOVE_FORWARD)
        return int(Action.TURN_LEFT if best_turns > 0 else Action.TURN_RIGHT)

    def act(self, observation: Any = None) -> int:
        """The next action (the observation is ignored)."""
        del observation
        state = self.env.state
        if not self._plan or self._expected is None or self._expected != state:
            self._plan = self._plan_actions(state)
        if not self._plan:
            self._expected = None
            return self._greedy()
        action = self._plan.pop(0)
        self._expected, _ = apply_action(self.env.grid, state, action, self.env.motion)
        return action


class RandomAgent:
    """Uniformly random actions (stop included), from its own seeded generator."""

    def __init__(self, env: NavEnv, seed: int = 0) -> None:
        self.env = env
        self.rng = np.random.default_rng(seed)

    def reset(self) -> None:
        return None

    def act(self, observation: Any = None) -> int:
        del observation
        return int(self.rng.integers(len(Action)))


@dataclass(frozen=True)
class EpisodeResult:
    episode_id: int
    success: bool
    spl: float
    distance_to_goal: float
    steps: int
    path_length: float


def run_episodes(
    env: NavEnv,
    make_agent: Callable[[NavEnv], OracleAgent | RandomAgent],
    episode_indices: list[int] | None = None,
    seed: int = 0,
) -> list[EpisodeResult]:
    """Run an agent over the env's episode set (or `len(episode_indices)` sampled ones)."""
    agent = make_agent(env)
    indices = episode_indices
    if indices is None:
        indices = list(range(len(env.episodes.episodes))) if env.episodes else list(range(10))
    results = []
    for n, index in enumerate(indices):
        options = {"episode_index": index} if env.episodes else None
        obs, info = env.reset(seed=seed if n == 0 else None, options=options)
        agent.reset()
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(agent.act(obs))
        results.append(
            EpisodeResult(
                episode_id=int(info["episode_id"]),
                success=bool(info["success"]),
                spl=float(info["spl"]),
                distance_to_goal=float(info["distance_to_goal"]),
                steps=int(info["steps"]),
                path_length=float(info["path_length"]),
            )
        )
    return results


def summarize(results: list[EpisodeResult]) -> dict[str, float]:
    """Mean success, SPL, final distance to goal and steps over episodes."""
    n = max(len(results), 1)
    return {
        "episodes": float(len(results)),
        "success": sum(r.success for r in results) / n,
        "spl": sum(r.spl for r in results) / n,
        "distance_to_goal": sum(min(r.distance_to_goal, 1e3) for r in results) / n,
        "steps": sum(r.steps for r in results) / n,
    }
