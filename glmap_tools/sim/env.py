"""gymnasium environments `glmap/ObjectNav-v0` and `glmap/InstNav-v0` in simulated apartments.

Observation (a Dict):
    rgb:   Box uint8 [H, W, 3]
    depth: Box float32 [H, W], metres along the optical axis, 0 where nothing was hit
    pose:  Box float32 [4, 4], world_from_camera (OpenCV camera, z-up world, metres)
    goal:  Text, the category name (ObjectNav) or the instance description (InstNav)

Actions: 0 stop, 1 move_forward (0.25 m), 2 turn_left (30 deg), 3 turn_right (30 deg).
An episode ends on stop (terminated) or after `max_steps` steps (truncated). Success: the
agent stopped within `success_distance` metres of a goal object's footprint surface (planar
distance from its centre to the footprint rectangle), with no wall in between.

`info` carries the perception of the frame (`instance_mask` [H, W] int32 and `annotation`
in the format of `glmap_tools.perception.annotated`): exact with `perception="gt"`, or with
the errors of a detector and a captioner with `"detector"` (`detector.py`), and the metrics
`success`, `spl`, `distance_to_goal` (geodesic metres), `path_length`, `collided`, `steps`.
"""

from __future__ import annotations

import math
import os
import string
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim.annotate import annotate_view, default_min_pixels
from glmap_tools.sim.detector import PERCEPTIONS, DetectorRates, detect_view, load_rates
from glmap_tools.sim.episodes import (
    MIN_START_DISTANCE,
    SUCCESS_DISTANCE,
    Episode,
    EpisodeSet,
    GoalPool,
    goal_distance_field,
    goal_pool,
    load_episodes,
    sample_episode,
    validate_episodes,
)
from glmap_tools.sim.layout import Layout
from glmap_tools.sim.layout_io import load_layout
from glmap_tools.sim.motion import Action, AgentState, MotionConfig, apply_action
from glmap_tools.sim.navgrid import NavGrid, build_nav_grid
from glmap_tools.sim.reach import reaches
from glmap_tools.sim.render import Z_FAR, CameraSpec, RenderedView, SceneRenderer
from glmap_tools.worlds.generator import generate_apartment

GOAL_CHARSET = string.ascii_letters + string.digits + " -',."
GOAL_MAX_LENGTH = 256
POSE_BOUND = 1e4  # metres; the pose Box's finite bounds
SLACK_REWARD = -0.01
SUCCESS_REWARD = 2.5


class NavEnv(gym.Env[dict[str, Any], np.int64]):
    """Shared ObjectNav/InstNav environment (see the module docstring).

    Args:
        layout: a `Layout`, a layout JSON path, or None to generate one from `scene_seed`.
        episodes: an `EpisodeSet` or episode JSON path; None samples episodes on reset.
        scene_seed: seed of the generated apartment when no layout is given.
        n_rooms: rooms of the generated apartment (3..7; drawn from the seed when None).
        camera: image size, horizontal FOV and camera height (default 640x480, 79 deg, 0.88 m).
        max_steps: steps before truncation.
        forward_step: metres per move_forward.
        turn_angle_deg: degrees per turn.
        success_distance: metres from a goal footprint that count as arrived.
        min_object_pixels: objects smaller in a frame are left out of the annotation.
        perception: "gt" (exact labels and masks) or "detector" (misses, confusions, false
            positives, bleeding masks, wrong colours: `sim/detector.py`).
        detector_rates: the detector's rates (default: the bundled `detector_rates.json`).
        render_mode: None or "rgb_array".
        grid: the layout's navigation grid when the caller already built it (shared by many
            environments on one scene, e.g. the benchmark's); built here when None.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}
    task = "objectnav"

    def __init__(
        self,
        layout: Layout | str | os.PathLike[str] | None = None,
        episodes: EpisodeSet | str | os.PathLike[str] | None = None,
        scene_seed: int = 0,
        n_rooms: int | None = None,
        camera: CameraSpec | None = None,
        max_steps: int = 500,
        forward_step: float = 0.25,
        turn_angle_deg: float = 30.0,
        success_distance: float = SUCCESS_DISTANCE,
        min_object_pixels: int | None = None,
        render_mode: str | None = None,
        grid: NavGrid | None = None,
        perception: str = "gt",
        detector_rates: DetectorRates | None = None,
    ) -> None:
        if perception not in PERCEPTIONS:
            raise InvalidInputError(f"perception={perception!r} is not one of {list(PERCEPTIONS)}.")
        if render_mode not in (None, "rgb_array"):
            raise InvalidInputError(f"render_mode={render_mode!r}; use None or 'rgb_array'.")
        if max_steps < 1:
            raise InvalidInputError(f"max_steps={max_steps} must be at least 1.")
        if isinstance(layout, Layout):
            self.layout = layout
        elif layout is not None:
            self.layout = load_layout(layout)
        else:
            self.layout = generate_apartment(scene_seed, n_rooms=n_rooms)
        self.camera = camera or CameraSpec()
        self.grid = grid if grid is not None else build_nav_grid(self.layout)
        self.motion = MotionConfig(forward_step, math.radians(turn_angle_deg))
        self.max_steps = int(max_steps)
        self.success_distance = float(success_distance)
        self.min_object_pixels = min_object_pixels
        self.perception = perception
        self.detector_rates = detector_rates or (load_rates() if perception == "detector" else None)
        self.render_mode = render_mode
        self.episodes: EpisodeSet | None = None
        if episodes is not None:
            self.episodes = (
                episodes
                if isinstance(episodes, EpisodeSet)
                else load_episodes(episodes, self.layout, self.grid)
            )
            if self.episodes.task != self.task:
                raise InvalidInputError(
                    f"episodes are for task {self.episodes.task!r} but this environment runs "
                    f"{self.task!r}; use the matching environment id."
                )
            if isinstance(episodes, EpisodeSet):
                validate_episodes(self.episodes, self.layout, self.grid)
            self.success_distance = self.episodes.success_distance
        self.renderer = SceneRenderer(self.layout, self.camera)
        h, w = self.camera.height, self.camera.width
        self.observation_space = spaces.Dict(
            {
                "rgb": spaces.Box(0, 255, (h, w, 3), dtype=np.uint8),
                "depth": spaces.Box(0.0, Z_FAR, (h, w), dtype=np.float32),
                "pose": spaces.Box(-POSE_BOUND, POSE_BOUND, (4, 4), dtype=np.float32),
                "goal": spaces.Text(GOAL_MAX_LENGTH, charset=GOAL_CHARSET),
            }
        )
        self.action_space = spaces.Discrete(len(Action))
        self._pool: GoalPool | None = None
        self._fields: dict[tuple[int, ...], np.ndarray] = {}
        self._episode_counter = 0
        self.episode: Episode | None = None
        self.state = AgentState(0.0, 0.0, 0.0)
        self.goal_field = np.zeros(self.grid.shape)
        self._view: RenderedView | None = None
        self._steps = 0
        self._path_length = 0.0
        self._over = True
        self._goal_seen = self._goal_recognised = False

    # ------------------------------------------------------------------ episodes
    def _next_episode(self, options: dict[str, Any]) -> Episode:
        if "episode" in options:
            episode = options["episode"]
            if not isinstance(episode, Episode):
                raise InvalidInputError("options['episode'] must be an Episode.")
            validate_episodes(
                EpisodeSet(
                    self.task, self.layout.name, self.layout.seed, [episode], self.success_distance
                ),
                self.layout,
                self.grid,
                fields=self._fields,
            )
            return episode
        if self.episodes is not None:
            n = len(self.episodes.episodes)
            index = options.get("episode_index")
            if index is None:
                index = int(self.np_random.integers(n))
            if not (isinstance(index, int) and 0 <= index < n):
                raise InvalidInputError(f"episode_index={index!r} must be in 0..{n - 1}.")
            return self.episodes.episodes[index]
        if self._pool is None:
            self._pool = goal_pool(
                self.layout, self.task, self.grid, self.success_distance, MIN_START_DISTANCE
            )
            self._fields.update({ids: field for _, ids, field in self._pool})
        self._episode_counter += 1
        return sample_episode(
            self.np_random, self.grid, self._pool, self.task, self._episode_counter - 1
        )

    def _field(self, ids: tuple[int, ...]) -> np.ndarray:
        if ids not in self._fields:
            targets = [self.layout.object(i) for i in ids]
            self._fields[ids] = goal_distance_field(self.grid, targets, self.success_distance)
        return self._fields[ids]

    # ------------------------------------------------------------------ metrics
    def distance_to_goal(self, state: AgentState | None = None) -> float:
        """Geodesic metres from `state` (default: the agent) to the nearest goal cell."""
        s = state or self.state
        r, c = self.grid.cell_of(s.x, s.y)
        h, w = self.grid.shape
        if not (0 <= r < h and 0 <= c < w):
            return math.inf
        return float(self.goal_field[r, c])

    def surface_distance(self, state: AgentState | None = None) -> float:
        """Planar metres from `state` to the nearest goal object's footprint."""
        s = state or self.state
        assert self.episode is not None
        return min(
            float(self.layout.object(i).distance_to(s.xy[None])[0])
            for i in self.episode.goal_object_ids
        )

    def reaches_goal(self, state: AgentState | None = None) -> bool:
        """Whether `state` is within the success distance of a goal footprint's surface
        with no wall in between (`reach.reaches`)."""
        s = state or self.state
        assert self.episode is not None
        return any(
            bool(reaches(self.grid, self.layout.object(i), s.xy[None], self.success_distance)[0])
            for i in self.episode.goal_object_ids
        )

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        if options is not None and not isinstance(options, dict):
            raise InvalidInputError(
                f"options={options!r:.60} must be a dict, e.g. {{'goal': 'a chair'}} or "
                "{'episode': 'tune/objectnav/s00-000'}."
            )
        super().reset(seed=seed)
        if seed is not None:
            self._episode_counter = 0  # sampled episodes are numbered from each seeding
        self.episode = self._next_episode(dict(options or {}))
        bad = sorted(set(self.episode.goal_text) - set(GOAL_CHARSET))
        if bad or not 0 < len(self.episode.goal_text) <= GOAL_MAX_LENGTH:
            raise InvalidInputError(
                f"episode {self.episode.episode_id} goal {self.episode.goal_text!r} has "
                f"characters {bad} outside the goal alphabet or is longer than "
                f"{GOAL_MAX_LENGTH}; use letters, digits, spaces and -',. only."
            )
        self.goal_field = self._field(self.episode.goal_object_ids)
        x, y = self.episode.start_position
        self.state = AgentState(float(x), float(y), float(self.episode.start_heading))
        self._steps, self._path_length, self._over = 0, 0.0, False
        self._goal_seen = self._goal_recognised = False
        obs = self._observe()
        return obs, self._info(collided=False, stopped=False)

    def step(
        self, action: np.int64 | int
    ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if self._over or self.episode is None:
            raise InvalidInputError("the episode is over (or never began); call reset() first.")
        whole = isinstance(action, int | np.integer) and not isinstance(action, bool | np.bool_)
        if not (whole and 0 <= int(action) < len(Action)):
            raise InvalidInputError(
                f"action {action!r} is not one of 0 stop, 1 move_forward, 2 turn_left, "
                "3 turn_right."
            )
        before = self.distance_to_goal()
        previous = self.state
        self.state, collided = apply_action(self.grid, self.state, int(action), self.motion)
        self._path_length += float(np.linalg.norm(self.state.xy - previous.xy))
        self._steps += 1
        stopped = int(action) == Action.STOP
        terminated = stopped
        truncated = not terminated and self._steps >= self.max_steps
        self._over = terminated or truncated
        obs = self._observe()
        info = self._info(collided, stopped)
        after = self.distance_to_goal()
        progress = before - after if math.isfinite(before) and math.isfinite(after) else 0.0
        reward = progress + SLACK_REWARD + (SUCCESS_REWARD if info["success"] else 0.0)
        return obs, float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        if self.render_mode != "rgb_array" or self._view is None:
            return None
        return self._view.rgb

    def close(self) -> None:
        self.renderer.close()
        super().close()

    # ------------------------------------------------------------------ frames
    def _observe(self) -> dict[str, Any]:
        assert self.episode is not None
        pose = self.state.pose(self.camera.camera_height)
        self._view = self.renderer.render(pose)
        return {
            "rgb": self._view.rgb,
            "depth": self._view.depth,
            "pose": pose.matrix.astype(np.float32),
            "goal": self.episode.goal_text,
        }

    def _info(self, collided: bool, stopped: bool) -> dict[str, Any]:
        assert self.episode is not None and self._view is not None
        mask, annotation = self._perceive(self._view)
        self._note_goal(self._view.instance_mask, annotation)
        success = bool(stopped and self.reaches_goal())
        shortest = self.episode.geodesic_distance
        spl = shortest / max(shortest, self._path_length, 1e-9) if success else 0.0
        return {
            "instance_mask": mask,
            "annotation": annotation,
            "episode_id": self.episode.episode_id,
            "goal_object_ids": list(self.episode.goal_object_ids),
            "success": success,
            "spl": float(spl),
            "distance_to_goal": self.distance_to_goal(),
            "path_length": self._path_length,
            "steps": self._steps,
            "collided": collided,
            "goal_seen": self._goal_seen,
            "goal_recognised": self._goal_recognised,
            "stopped_at_goal_category": stopped and not success and self._at_goal_category(),
            "position": self.state.xy.copy(),
            "heading": self.state.heading,
        }

    def _at_goal_category(self) -> bool:
        """Whether the agent is within reach of an object of the goal's category that is not
        a goal (InstNav: another instance than the described one)."""
        assert self.episode is not None
        goals = set(self.episode.goal_object_ids)
        category = self.layout.object(self.episode.goal_object_ids[0]).category
        xy = self.state.xy[None]
        return any(
            bool(reaches(self.grid, o, xy, self.success_distance)[0])
            for o in self.layout.objects
            if o.category == category and o.id not in goals
        )

    def _note_goal(self, instance_mask: np.ndarray, annotation: dict[str, Any]) -> None:
        """Whether a goal object was ever in view (as many pixels as a detection needs)
        and ever perceived with the goal's category (the failure taxonomy's ground truth)."""
        assert self.episode is not None
        goals = self.episode.goal_object_ids
        h, w = instance_mask.shape
        need = self.min_object_pixels or default_min_pixels(h, w)
        counts = np.bincount(instance_mask.ravel(), minlength=max(goals) + 1)
        if any(counts[i] >= need for i in goals):
            self._goal_seen = True
        category = self.layout.object(goals[0]).category
        if any(o["id"] in goals and o["label"] == category for o in annotation["objects"]):
            self._goal_recognised = True

    def _perceive(self, view: RenderedView) -> tuple[np.ndarray, dict[str, Any]]:
        if self.perception == "gt":
            return annotate_view(view.instance_mask, self.layout, self.min_object_pixels)
        assert self.episode is not None
        if self.detector_rates is None:
            self.detector_rates = load_rates()
        episode = self.episode
        goal = self.layout.object(episode.goal_object_ids[0]).category
        key = f"{self.task}/{episode.episode_id}/{episode.start_position}/{episode.goal_text}"
        return detect_view(
            view.instance_mask,
            view.depth,
            self.layout,
            self.camera.intrinsics,
            self.state.pose(self.camera.camera_height).matrix,
            goal_category=goal,
            episode=key,
            rates=self.detector_rates,
            min_pixels=self.min_object_pixels,
        )


class ObjectNavEnv(NavEnv):
    """ObjectNav: find any instance of a category ("chair")."""

    task = "objectnav"


class InstNavEnv(NavEnv):
    """InstNav: find the one instance a description singles out."""

    task = "instnav"
