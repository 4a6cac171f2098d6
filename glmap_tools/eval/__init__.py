"""Navigation evaluation: `glmap eval`, SR/SPL tables with bootstrap intervals, resumable runs.

Episodes of the benchmark split (`glmap_tools.worlds.splits`) are played by the agents of
`agents.runner` through in-memory MCP sessions, on local worker processes or a Ray cluster.
See docs/evaluation.md.
"""

from glmap_tools.eval.spec import EvalSpec, episode_seed, parse_agents, select_episodes
from glmap_tools.eval.stats import (
    Interval,
    bootstrap_mean,
    bootstrap_mean_reference,
    paired_difference,
)
from glmap_tools.eval.table import Summary, markdown, summarize

__all__ = [
    "EvalSpec",
    "Interval",
    "Summary",
    "bootstrap_mean",
    "bootstrap_mean_reference",
    "episode_seed",
    "markdown",
    "paired_difference",
    "parse_agents",
    "select_episodes",
    "summarize",
]
