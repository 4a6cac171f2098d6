"""The ObjectNav agent loop: one MCP tool call per step (or per few steps) until the episode ends.

Map-based agents (glmap, glmap-instance, glmap-region, egocentric, frontier) call the
server's `nav_step` tool: the policy runs server-side (`glmap_tools.nav.decide`: value map,
frontiers, waypoint, FMM plan) on the session's map, the chosen action is taken, and the
new frame is integrated, so one call costs one render + integrate + value map + plan. The
random agent draws uniform actions (move_forward / turn_left / turn_right) from its own
seeded generator and calls `sim_step`; it never stops by itself, so it ends at the step limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.fs import RegionScorer, region_views
from agents.trace import TracedClient

MAP_POLICIES = ("glmap", "glmap-instance", "glmap-region", "egocentric", "frontier")
RANDOM_ACTIONS = ("move_forward", "turn_left", "turn_right")


@dataclass
class StepRecord:
    """One action of the episode as the report shows it.

    Attributes:
        step: the env step after the action (1-based).
        action: the action taken.
        position: [x, y] metres after the action.
        heading_deg: heading after the action (CCW from +x).
        waypoint: the policy's waypoint {kind, xy, unit_id, score} (map policies only).
        reason: why the policy chose it.
        images: egocentric view and value map files of this step, when fetched.
        call: the tool call that took the action.
    """

    step: int
    action: str
    position: list[float]
    heading_deg: float
    waypoint: dict[str, Any] | None = None
    reason: str = ""
    images: list[str] = field(default_factory=list)
    call: int = 0


@dataclass
class Play:
    """What an episode produced: the first and last status and every step."""

    start: dict[str, Any]
    final: dict[str, Any]
    steps: list[StepRecord]


class NavAgent:
    """Plays one episode already started with sim_reset.

    Args:
        policy: an agent name (`MAP_POLICIES` or 'random').
        seed: seeds the random agent's actions.
        actions_per_call: env steps one nav_step call may take (the policy replans
            before each one); 1 gives a decision per call in the trace.
        image_every: fetch the egocentric view and the value map every this many calls
            (for the report); 0 = never.
        task: 'objectnav' or 'instnav' (the goal is a category or a description).
    """

    task = "objectnav"

    def __init__(
        self,
        policy: str,
        seed: int = 0,
        actions_per_call: int = 1,
        image_every: int = 10,
        fs: RegionScorer | None = None,
    ) -> None:
        if policy not in (*MAP_POLICIES, "random"):
            raise ValueError(f"unknown policy {policy!r}")
        self.policy = policy
        self.rng = np.random.default_rng(seed)
        self.actions_per_call = max(1, int(actions_per_call))
        self.image_every = int(image_every)
        self.fs = fs
        self.scored: dict[int, str] = {}  # region id -> what its score was computed from
        self.given: dict[int, float] = {}  # region id -> the score sent

    async def give_scores(self, client: TracedClient, goal: str) -> None:
        """Score the regions that are new or changed since the last call with `self.fs`
        and send the scores that changed with value_map (one call, only when needed)."""
        assert self.fs is not None
        regions = await client.resource("glmap://current/regions")
        changed = [r for r in regions if self.scored.get(int(r["id"])) != _key(r)]
        if not changed:
            return
        self.scored.update({int(r["id"]): _key(r) for r in changed})
        instances = await client.resource("glmap://current/instances")
        scores = self.fs.score(goal, region_views(changed, instances))
        new = {uid: s for uid, s in scores.items() if self.given.get(uid) != s}
        if new:
            self.given.update(new)
            await client.call(
                "value_map", {"scores": {str(k): v for k, v in new.items()}}, keep_images=False
            )

    def _images_now(self, n_calls: int, status: dict[str, Any]) -> bool:
        return self.image_every > 0 and n_calls % self.image_every == 0

    async def play(self, client: TracedClient, start: dict[str, Any]) -> Play:
        """Act until the episode ends (stop or the step limit); return what happened."""
        steps: list[StepRecord] = []
        status = start
        calls = 0
        while status["status"] == "running":
            images = self._images_now(calls, status)
            if self.policy == "random":
                action = str(self.rng.choice(RANDOM_ACTIONS))
                record = await client.call("sim_step", {"action": action}, keep_images=images)
                status = record.data()
                steps.append(
                    StepRecord(
                        status["steps"],
                        action,
                        status["position"],
                        status["heading_deg"],
                        images=record.images,
                        call=record.call,
                    )
                )
            else:
                if self.fs is not None:
                    await self.give_scores(client, start["goal"])
                args = {
                    "policy": self.policy,
                    "actions": self.actions_per_call,
                    "execute_stop": True,
                    "details": True,
                    "images": images,
                }
                record = await client.call("nav_step", args, keep_images=images)
                status = record.data()
                for k, s in enumerate(status.pop("decisions")):
                    steps.append(
                        StepRecord(
                            s["step"],
                            s["action"],
                            s["position"],
                            s["heading_deg"],
                            s.get("waypoint"),
                            (s.get("waypoint") or {}).get("reason", ""),
                            record.images if k == 0 else [],
                            record.call,
                        )
                    )
            calls += 1
        return Play(start, status, steps)


def _key(region: dict[str, Any]) -> str:
    """What a region's score depends on: its text and its members."""
    return f"{region['description']}|{sorted(region.get('instance_ids', []))}"
