"""The one episode step: observation -> frame and semantics -> integrate -> decide -> act.

Every loop that plays an episode runs this step: the MCP tools (through the app, which adds
only locks and sessions), the bench loops and the replay check. A step is

- `observation_frame`: the simulator's observation as a posed RGB-D frame and its
  semantics (the one conversion);
- `observe`: the frame into the map, then into the policy's memory (`remember`: the units
  the look missed, and the egocentric accumulator fed with the frame score);
- `decide` (`nav.policy`): the next action's name, whose index in `ACTIONS` is the
  simulator's action id.

`play` runs whole episodes of a gymnasium env with this step.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from glmap_tools.geometry import Pose
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.nav.config import ACTIONS, NavConfig
from glmap_tools.nav.egocentric import EgocentricValueMap
from glmap_tools.nav.perceive import TextVectors, frame_score
from glmap_tools.nav.policy import NavDecision, decide
from glmap_tools.nav.scorers import EmbeddingScorer
from glmap_tools.nav.state import NavState
from glmap_tools.nav.verify import note_missed
from glmap_tools.perception.annotated import semantics_from_annotation

if TYPE_CHECKING:
    from glmap_tools.geometry.camera import Intrinsics
    from glmap_tools.map.glmap import GLMap
    from glmap_tools.map.report import UpdateReport
    from glmap_tools.nav.scorers import Scorer
    from glmap_tools.perception.semantics import FrameSemantics


def observation_frame(
    obs: Mapping[str, Any], info: Mapping[str, Any], intrinsics: Intrinsics
) -> tuple[RGBDFrame, FrameSemantics]:
    """The simulator's observation as a posed RGB-D frame with its annotations' semantics.

    Args:
        obs: {"rgb": [H, W, 3] uint8, "depth": [H, W] float32 metres, "pose": [4, 4]
            float32 world_from_camera}.
        info: {"instance_mask": [H, W] ids, "annotation": {"objects", "groups"}}.
        intrinsics: the env's camera.

    The pose arrives as float32 (the env's observation space): rigid to about 1e-7, well
    within `Pose`'s tolerance, so it is taken as it is. Re-orthonormalising it would only
    round it another way (the env's float64 pose is not recoverable) and change the bits of
    every map built from the simulator.
    """
    pose = Pose(np.asarray(obs["pose"], dtype=np.float64))
    frame = RGBDFrame(obs["rgb"], obs["depth"], intrinsics, pose)
    return frame, semantics_from_annotation(info["instance_mask"], info["annotation"])


def agent_of(info: Mapping[str, Any]) -> tuple[float, float, float]:
    """(x, y, heading) of the agent in the env's info: metres, radians CCW from +x."""
    x, y = (float(v) for v in info["position"])
    return x, y, float(info["heading"])


def remember(
    state: NavState,
    glmap: GLMap,
    frame: RGBDFrame,
    score: float,
) -> None:
    """The policy's memory of one frame already integrated into `glmap`: the units it
    looked at without seeing (`verify.note_missed`, read by the glmap policies) and its
    goal score over its view cone (the egocentric accumulator, read by 'egocentric')."""
    note_missed(state.missed, glmap, frame)
    feed_egocentric(state, frame, score, glmap.grid.cell_size, glmap.config.max_range)


def feed_egocentric(
    state: NavState, frame: RGBDFrame, score: float, cell: float, reach: float
) -> None:
    """Add a frame's goal score to the egocentric accumulator (made on the first frame with
    the map's `cell` size and depth `reach`, metres)."""
    if state.egocentric is None:
        state.egocentric = EgocentricValueMap(cell, reach)
    state.egocentric.add_frame(frame, score)


def observe(
    glmap: GLMap,
    frame: RGBDFrame,
    semantics: FrameSemantics,
    state: NavState,
    goal: str,
    scorer: Scorer,
    texts: TextVectors | None = None,
) -> UpdateReport:
    """Integrate one frame into the map and the policy's memory (`remember`).

    Args:
        scorer: f_S for the frame score (the goal against what the frame shows).
        texts: embeddings of texts already seen, kept over the episode (None: embed them).

    Returns:
        The map's update report.
    """
    report = glmap.integrate(frame, semantics)
    remember(state, glmap, frame, frame_score(glmap, goal, scorer, semantics, texts))
    return report


@dataclass
class Step:
    """One step of an episode played by `play`.

    Attributes:
        frame, semantics: the observation as the map took it.
        report: the map's update report.
        agent: (x, y, heading) where the agent decided.
        seen: the env's info of the observation (its annotation, step count).
        decision: what the policy chose.
        info: the env's info after the action (collided; success, spl at the end).
        over: the episode ended with this action.
        seconds: process CPU seconds of 'integrate' (with the memory update), 'decide'
            and 'act' (the env's step: move, render, annotate), and the wall seconds of
            the whole step ('wall').
    """

    frame: RGBDFrame
    semantics: FrameSemantics
    report: UpdateReport
    agent: tuple[float, float, float]
    seen: Mapping[str, Any]
    decision: NavDecision
    info: Mapping[str, Any]
    over: bool
    seconds: dict[str, float]


def play(
    env: Any,
    glmap: GLMap,
    policy: str,
    config: NavConfig,
    options: Mapping[str, Any] | None = None,
    seed: int = 0,
    state: NavState | None = None,
) -> Iterator[Step]:
    """Play one episode of `env` (a glmap simulator env) with `policy`, a `Step` at a time.

    The env is reset with `seed` and `options`; the goal is the observation's. The last
    step yielded has `over` set.
    """
    obs, seen = env.reset(seed=seed, options=dict(options or {}))
    state = state if state is not None else NavState()
    if state.scorer is None:
        state.scorer = EmbeddingScorer(glmap.embedder)
    texts = TextVectors(glmap.embedder)
    goal = str(obs["goal"])
    while True:
        wall = time.perf_counter()
        t0 = time.process_time()
        frame, semantics = observation_frame(obs, seen, env.camera.intrinsics)
        report = observe(glmap, frame, semantics, state, goal, state.scorer, texts)
        t1 = time.process_time()
        agent = agent_of(seen)
        d = decide(glmap, agent[:2], agent[2], goal, policy=policy, state=state, config=config)
        t2 = time.process_time()
        obs, _, terminated, truncated, info = env.step(ACTIONS.index(d.action))
        t3 = time.process_time()
        over = bool(terminated or truncated)
        seconds = {"integrate": t1 - t0, "decide": t2 - t1, "act": t3 - t2}
        seconds["wall"] = time.perf_counter() - wall
        yield Step(frame, semantics, report, agent, seen, d, info, over, seconds)
        if over:
            return
        seen = info
