"""A session's simulator episode: a navigation env, driven on one thread, frames for the map.

The simulator renders with one process-wide OpenGL (EGL) context per image size, and a
context can be current on one thread only. So every env call of every session (create,
reset, step, close) runs on one process-wide simulator thread, which releases the context
after each call.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from glmap_tools.app.sim_results import SimStatus
from glmap_tools.errors import InvalidInputError, did_you_mean

if TYPE_CHECKING:
    from glmap_tools.geometry.frame import RGBDFrame
    from glmap_tools.perception.semantics import FrameSemantics
    from glmap_tools.sim.env import NavEnv
    from glmap_tools.worlds.scene_dirs import BenchEpisode, SceneDirs

# Imports inside functions stay there: cv2, gaussians, gymnasium, language.embed, numba, pyrender,
# scipy, sim.episodes, numba, trimesh, worlds.scene_dirs load on first use: build_server stays light
# (test_server_startup): the server loads them in the background or on first use; the tools load
# before these do, in the server and the in-process toolset alike.

T = TypeVar("T")
TASKS = ("objectnav", "instnav")
MAX_GOALS_LISTED = 25
EPISODE_RESET = (
    "the episode was reset by another call (sim_reset) while this action waited, so it was "
    "not taken; look at the new episode (sim_reset's reply, or map_summary) and act again."
)

_thread_lock = threading.Lock()
_thread: ThreadPoolExecutor | None = None


def on_sim_thread(fn: Callable[..., T], *args: object) -> T:
    """Run fn(*args) on the process-wide simulator thread; return its result or raise."""
    global _thread
    with _thread_lock:
        if _thread is None:
            _thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="glmap-sim")
        executor = _thread

    def call() -> T:
        try:
            return fn(*args)
        finally:
            _release_context()

    return executor.submit(call).result()


def _release_context() -> None:
    """Make no EGL context current on this thread, so another thread may render."""
    from glmap_tools.sim.render import release_current_context

    release_current_context()


@dataclass
class SimEpisode:
    """One env and the state of its current episode.

    Attributes:
        task: 'objectnav' or 'instnav'.
        scene: seed of the generated apartment (-1 for a benchmark scene).
        env: the gymnasium env (used on the simulator thread only).
        key: what the env was built for; a reset with the same key reuses it.
        bench: the `glmap_tools.worlds.splits.BenchEpisode` being played, or None.
        obs, info: the latest observation and info.
        over: whether the episode ended (stop or step limit).
        truncated: whether it ended by the step limit.
        collisions: steps of this episode that bumped into something.
        started: (seed, goal) of the latest reset, None before one.
        actions: the action numbers taken since it (with `started`, a replay of the episode).
        resets: how many times it was reset (an action asked for before a reset it did not
            see is refused, not played in the new episode).
        closed: the env was closed (a sim_reset to another scene replaced it).
    """

    task: str
    scene: int
    env: NavEnv
    key: tuple[Any, ...] = ()  # (task or "bench", scene, size, max_steps): reopen when it changes
    bench: BenchEpisode | None = None  # the benchmark episode this env plays, if any
    obs: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    over: bool = False
    truncated: bool = False
    collisions: int = 0
    started: tuple[int, str | None] | None = None
    actions: list[int] = field(default_factory=list)
    pool: list[tuple[str, tuple[int, ...], np.ndarray]] | None = None
    resets: int = 0
    closed: bool = False

    def run(self, fn: Callable[..., T], *args: object) -> T:
        """Run fn(*args) on the simulator thread and return its result."""
        return on_sim_thread(fn, *args)

    def close(self) -> None:
        def shut() -> None:
            if not self.closed:
                self.closed = True
                self.env.close()

        self.run(shut)


def perception_of(perception: str, bench: BenchEpisode | None = None) -> str:
    """'gt' or 'detector': `perception`, or for 'auto' the split's own ('gt' off a split)."""
    if perception != "auto":
        return perception
    return str(getattr(bench, "perception", None) or "gt") if bench is not None else "gt"


def open_episode(
    task: str, scene: int, size: tuple[int, int], max_steps: int, perception: str = "auto"
) -> SimEpisode:
    """Create the env for (task, scene) on the simulator thread.

    Raises:
        InvalidInputError: an unknown task.
    """
    if task not in TASKS:
        raise InvalidInputError(f"task {task!r} is not one of {TASKS}.{did_you_mean(task, TASKS)}")
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

    def make() -> NavEnv:
        from glmap_tools.sim.env import InstNavEnv, ObjectNavEnv
        from glmap_tools.sim.render import CameraSpec

        cls = ObjectNavEnv if task == "objectnav" else InstNavEnv
        return cls(
            scene_seed=scene,
            camera=CameraSpec(width=size[0], height=size[1]),
            max_steps=max_steps,
            perception=perception_of(perception),
        )

    return SimEpisode(task, scene, on_sim_thread(make), key=(task, scene, size, max_steps))


def bench_episode(episode_id: str, scene_dirs: SceneDirs | None = None) -> BenchEpisode:
    """The benchmark episode `episode_id` (e.g. 'bench/objectnav/s03-017'), or one of the
    scene folders `scene_dirs` (`ServerConfig.scene_dirs`) by name ('mine/objectnav/k-003').

    Raises:
        UnknownIdError: no such episode (the message suggests the closest id).
    """
    from glmap_tools.worlds.splits import bench_episode as lookup

    return lookup(episode_id, scene_dirs)


def open_bench(
    bench: BenchEpisode, size: tuple[int, int], max_steps: int, perception: str = "auto"
) -> SimEpisode:
    """Create the env of a benchmark episode's scene on the simulator thread."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

    def make() -> NavEnv:
        from glmap_tools.sim.render import CameraSpec
        from glmap_tools.worlds.splits import make_env

        camera = CameraSpec(width=size[0], height=size[1])
        return make_env(bench, camera, max_steps, perception_of(perception, bench))

    key = ("bench", str(bench.layout_path), bench.task, size, max_steps)
    return SimEpisode(bench.task, -1, on_sim_thread(make), key=key, bench=bench)


def _goals(sim: SimEpisode) -> list[tuple[str, tuple[int, ...], np.ndarray]]:
    if sim.pool is None:
        from glmap_tools.sim.episodes import MIN_START_DISTANCE, goal_pool

        env = sim.env
        sim.pool = goal_pool(
            env.layout, sim.task, env.grid, env.success_distance, MIN_START_DISTANCE
        )
    return sim.pool


def reset(sim: SimEpisode, seed: int, goal: str | None) -> None:
    """Start an episode: the benchmark one, a random one from `seed`, or one for `goal`.

    Raises:
        InvalidInputError: `goal` is not a goal of this scene (the message lists them).
    """

    def run() -> None:
        env = sim.env
        options: dict[str, Any] = {}
        if sim.bench is not None:
            options["episode"] = sim.bench.episode
        elif goal is not None:
            from glmap_tools.sim.episodes import sample_episode

            pool = _goals(sim)
            wanted = goal.strip().lower()
            match = [entry for entry in pool if entry[0].lower() == wanted]
            if not match:
                texts = [entry[0] for entry in pool]
                shown = texts[:MAX_GOALS_LISTED] + (
                    ["..."] if len(texts) > MAX_GOALS_LISTED else []
                )
                raise InvalidInputError(
                    f"goal {goal!r} is not in scene {sim.scene} for {sim.task}."
                    f"{did_you_mean(goal, texts)} Goals here: {shown}; or omit goal for a "
                    "random one."
                )
            rng = np.random.default_rng(seed)
            options["episode"] = sample_episode(rng, env.grid, match, sim.task, seed)
        sim.obs, sim.info = env.reset(seed=seed, options=options)
        sim.over = sim.truncated = False
        sim.collisions = 0
        sim.started = (seed, goal)
        sim.actions = []
        sim.resets += 1

    sim.run(run)


def step(sim: SimEpisode, action: str, resets: int | None = None) -> None:
    """Take one action.

    Args:
        sim: the episode.
        action: one of `nav.ACTIONS` (the env's action id is its index).
        resets: `sim.resets` when the caller looked at the episode; the action is refused if
            the episode was reset since (None: not checked).

    Raises:
        InvalidInputError: an unknown action, the episode is over, or it was reset or
            replaced by another call since the caller looked (nothing is done then).
    """
    from glmap_tools.nav.config import ACTIONS

    if action not in ACTIONS:
        raise InvalidInputError(
            f"action {action!r} is not one of {list(ACTIONS)}.{did_you_mean(action, ACTIONS)}"
        )

    def run() -> None:  # on the simulator thread, where close and reset run too
        if sim.closed or (resets is not None and sim.resets != resets):
            raise InvalidInputError(EPISODE_RESET)
        if sim.over:
            raise InvalidInputError("the episode is over; call sim_reset to start another.")
        sim.obs, _, terminated, truncated, sim.info = sim.env.step(ACTIONS.index(action))
        sim.over = bool(terminated or truncated)
        sim.truncated = bool(truncated)
        sim.collisions += int(bool(sim.info["collided"]))
        sim.actions.append(ACTIONS.index(action))

    sim.run(run)


def agent_pose(sim: SimEpisode) -> tuple[float, float, float]:
    """(x, y, heading) of the agent: metres, radians CCW from +x."""
    from glmap_tools.nav.episode import agent_of

    return agent_of(sim.info)


def frame(sim: SimEpisode) -> tuple[RGBDFrame, FrameSemantics]:
    """The latest observation as a posed RGB-D frame with the simulator's annotations
    (`nav.episode.observation_frame`)."""
    from glmap_tools.nav.episode import observation_frame

    return observation_frame(sim.obs, sim.info, sim.env.camera.intrinsics)


def status(sim: SimEpisode, camera_pose: bool = True) -> SimStatus:
    """What the agent may know: goal, pose, steps, collisions; metrics once the episode ends.

    Args:
        sim: the episode.
        camera_pose: give the 4x4 camera pose too (sim_reset and sim_step do).
    """
    info = sim.info
    x, y = (float(v) for v in info["position"])
    out: dict[str, object] = {
        "task": sim.task,
        "scene": sim.bench.scene if sim.bench is not None else sim.scene,
        "goal": sim.obs["goal"],
        "steps": int(info["steps"]),
        "max_steps": sim.env.max_steps,
        "position": (round(x, 3), round(y, 3)),
        "heading_deg": round(math.degrees(float(info["heading"])), 1),
    }
    if camera_pose:
        out["camera_pose"] = np.round(np.asarray(sim.obs["pose"], np.float64), 4).tolist()
    out.update(collided=bool(info["collided"]), collisions=sim.collisions, status="running")
    if sim.bench is not None:
        out["episode"] = sim.bench.episode_id
    if sim.over:
        if info["success"]:
            out["status"] = "success"
        else:
            out["status"] = "out of steps" if sim.truncated else "stopped, not at the goal"
        out["success"] = bool(info["success"])
        out["spl"] = round(float(info["spl"]), 4)
        out["distance_to_goal"] = round(float(info["distance_to_goal"]), 3)
        out["path_length"] = round(float(info["path_length"]), 3)
        from glmap_tools.sim.outcome import episode_outcome

        out["episode_outcome"] = episode_outcome(
            bool(info["success"]),
            sim.truncated,
            float(info["distance_to_goal"]),
            bool(info.get("goal_seen", True)),
            bool(info.get("goal_recognised", True)),
            bool(info.get("stopped_at_goal_category", False)),
        )
    return SimStatus.model_validate(out)
