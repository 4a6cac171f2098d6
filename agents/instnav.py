"""The InstNav agent: the ObjectNav loop with a description as the goal.

The goal is one instance singled out by a description ("the blue armchair by the
window"). The server-side policy scores every map unit's text against the whole
description, so the value map favours the instance (and the region) whose text matches it
best, and the stop rule asks that one unit to match; everything else is the shared loop
of `agents.objectnav`.
"""

from __future__ import annotations

from typing import Any

from agents.objectnav import NavAgent


class InstNavAgent(NavAgent):
    """Plays an InstNav episode (see `agents.objectnav.NavAgent`)."""

    task = "instnav"


def agent_for(task: str, policy: str, seed: int, **options: Any) -> NavAgent:
    """The agent class of `task` ('objectnav' or 'instnav') with `policy`."""
    cls = InstNavAgent if task == "instnav" else NavAgent
    return cls(policy, seed, **options)
