"""gymnasium envs: contract, determinism, ground-truth perception, metrics, agents."""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import glmap_tools.sim  # noqa: F401  (registers the env ids)
from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose, backproject
from glmap_tools.perception.annotated import semantics_from_annotation
from glmap_tools.sim.agents import OracleAgent, RandomAgent, run_episodes, summarize
from glmap_tools.sim.env import InstNavEnv, ObjectNavEnv
from glmap_tools.sim.episodes import generate_episodes
from glmap_tools.sim.motion import Action
from glmap_tools.sim.render import CameraSpec
from glmap_tools.worlds.generator import generate_apartment

SMALL = CameraSpec(160, 120)


@pytest.fixture(scope="module")
def layout():
    return generate_apartment(5, n_rooms=3)


@pytest.fixture(scope="module")
def env(layout):
    return ObjectNavEnv(layout=layout, camera=SMALL)


@pytest.mark.parametrize("env_id", ["glmap/ObjectNav-v0", "glmap/InstNav-v0"])
def test_both_registered_envs_pass_the_gymnasium_env_checker(env_id, layout) -> None:
    env = gym.make(env_id, layout=layout, camera=SMALL)
    check_env(env.unwrapped, skip_render_check=False)
    obs, _ = env.reset(seed=0)
    assert obs["rgb"].shape == (120, 160, 3) and obs["depth"].dtype == np.float32
    assert env.observation_space["goal"].contains(obs["goal"])


def test_two_seeded_rollouts_are_identical(layout) -> None:
    def rollout() -> list:
        env = InstNavEnv(layout=layout, camera=SMALL)
        obs, info = env.reset(seed=11)
        frames = [(obs["goal"], obs["rgb"].copy(), obs["pose"].copy(), info["annotation"])]
        rng = np.random.default_rng(4)
        for _ in range(15):
            obs, reward, terminated, truncated, info = env.step(int(rng.integers(1, 4)))
            frames.append((reward, obs["rgb"].copy(), obs["depth"].copy(), info["annotation"]))
            if terminated or truncated:
                break
        return frames

    a, b = rollout(), rollout()
    assert len(a) == len(b)
    for fa, fb in zip(a, b, strict=True):
        for xa, xb in zip(fa, fb, strict=True):
            if isinstance(xa, np.ndarray):
                np.testing.assert_array_equal(xa, xb)
            else:
                assert xa == xb


def test_the_annotation_feeds_the_core_and_lists_exactly_the_mask_ids(env, layout) -> None:
    env.reset(seed=2)
    checked = 0
    for action in [2] * 12:
        _, _, _, _, info = env.step(action)
        mask, annotation = info["instance_mask"], info["annotation"]
        semantics = semantics_from_annotation(mask, annotation)  # raises when malformed
        listed = {o["id"] for o in annotation["objects"]}
        assert set(np.unique(mask)) - {0} == listed
        for g in annotation["groups"]:
            assert set(g["members"]) <= listed
            region = next(r for r in layout.regions if r.id == g["id"])
            assert set(g["members"]) == set(region.members) & listed
        checked += len(semantics.objects)
    assert checked > 0


def test_every_labelled_pixel_back_projects_inside_its_own_object(env, layout) -> None:
    env.reset(seed=3)
    by_id = layout.objects_by_id
    for action in [2, 2, 2, 1, 2, 2, 2]:
        obs, _, _, _, info = env.step(action)
        intrinsics = env.renderer.intrinsics
        pose = Pose(obs["pose"].astype(np.float64))
        for object_id in np.unique(info["instance_mask"]):
            if object_id == 0:
                continue
            pts = backproject(
                obs["depth"], intrinsics, pose, mask=info["instance_mask"] == object_id
            )
            obj = by_id[int(object_id)]
            assert obj.distance_to(pts.points[:, :2]).max() < 0.01
            assert pts.points[:, 2].min() > obj.position[2] - 0.01
            assert pts.points[:, 2].max() < obj.top + 0.01


def test_depth_of_the_floor_back_projects_to_height_zero(env) -> None:
    obs, info = env.reset(seed=4)
    heights = []
    for turn in range(12):
        if turn:
            obs, _, _, _, info = env.step(int(Action.TURN_LEFT))
        lower = np.zeros(obs["depth"].shape, dtype=bool)
        lower[-25:, :] = True  # rows looking down at the floor (or walls and furniture)
        background = lower & (info["instance_mask"] == 0)
        pose = Pose(obs["pose"].astype(np.float64))
        heights.append(
            backproject(obs["depth"], env.renderer.intrinsics, pose, mask=background).points[:, 2]
        )
    z = np.concatenate(heights)
    assert z.min() > -2e-3  # nothing below the floor
    assert (np.abs(z) < 2e-3).sum() > 2000  # and plenty of floor exactly at z = 0


def test_walking_into_a_wall_stops_at_the_wall(env) -> None:
    env.reset(seed=5)
    collided = False
    for _ in range(120):
        _, _, terminated, truncated, info = env.step(int(Action.MOVE_FORWARD))
        collided |= info["collided"]
        assert env.grid.is_navigable(env.state.xy[None])[0]
        if terminated or truncated:
            break
    assert collided


def test_stopping_far_from_the_goal_fails_with_zero_spl(env) -> None:
    _, info = env.reset(seed=6)
    assert info["distance_to_goal"] > 1.0
    _, reward, terminated, truncated, info = env.step(int(Action.STOP))
    assert terminated and not truncated
    assert info["success"] is False and info["spl"] == 0.0
    with pytest.raises(InvalidInputError, match="call reset"):
        env.step(int(Action.MOVE_FORWARD))


def test_an_episode_is_truncated_after_max_steps(layout) -> None:
    env = ObjectNavEnv(layout=layout, camera=SMALL, max_steps=3)
    env.reset(seed=0)
    flags = [env.step(int(Action.TURN_LEFT))[2:4] for _ in range(3)]
    assert flags == [(False, False), (False, False), (False, True)]


def test_the_oracle_succeeds_and_the_random_agent_rarely_does(layout) -> None:
    for task, env_cls in (("objectnav", ObjectNavEnv), ("instnav", InstNavEnv)):
        episodes = generate_episodes(layout, task, 6, seed=1)
        env = env_cls(layout=layout, episodes=episodes, camera=CameraSpec(32, 24))
        oracle = summarize(run_episodes(env, OracleAgent))
        random = summarize(run_episodes(env, lambda e: RandomAgent(e, 0)))
        assert oracle["success"] >= 0.95 and oracle["spl"] > 0.8, (task, oracle)
        assert random["success"] <= 0.35, (task, random)


def test_an_invalid_action_is_refused(env) -> None:
    env.reset(seed=0)
    for action in (7, 2**70, "1", 1.0, float("nan"), None, True, [1]):
        with pytest.raises(InvalidInputError, match="not one of 0 stop"):
            env.step(action)
    env.step(np.int64(2))  # numpy integers are actions
    with pytest.raises(InvalidInputError, match=r"options=\['goal'\] must be a dict"):
        env.reset(options=["goal"])


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ({"width": 0}, "width=0 must be a whole number of pixels in 1..4096"),
        ({"height": 48.5}, "height=48.5"),
        ({"camera_height": -1.0}, r"camera_height=-1.0 m must lie above the floor"),
        ({"camera_height": 9.0}, r"in \(0, 2.5\] m"),
        ({"camera_height": float("nan")}, "camera_height=nan"),
        ({"hfov_deg": 179.0}, "hfov_deg=179.0"),
    ],
)
def test_a_camera_outside_the_rooms_or_the_image_limits_is_refused(spec, match) -> None:
    with pytest.raises(InvalidInputError, match=match):
        CameraSpec(**{"width": 64, "height": 48, **spec})
    assert CameraSpec(np.int64(64), np.int64(48), 79.0, np.float32(0.5)).width == 64
