"""Simulated apartments: layouts, procedural generation, rendering, gymnasium envs, QA.

Importing this package registers `glmap/ObjectNav-v0` and `glmap/InstNav-v0`.
"""

from __future__ import annotations

import gymnasium

ENV_IDS = {
    "glmap/ObjectNav-v0": "glmap_tools.sim.env:ObjectNavEnv",
    "glmap/InstNav-v0": "glmap_tools.sim.env:InstNavEnv",
}


def register_envs() -> None:
    """Register the environments with gymnasium (idempotent)."""
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point)


register_envs()

__all__ = ["ENV_IDS", "register_envs"]
