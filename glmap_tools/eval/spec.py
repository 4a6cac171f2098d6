"""What an evaluation runs: task, split (or scene folder), episode selection, agents, seeds,
camera and limits."""

from __future__ import annotations

import functools
import hashlib
import json
import zlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from agents.runner import AGENT_SIZE, AGENTS
from glmap_tools.errors import InvalidInputError, did_you_mean
from glmap_tools.language.backends import SCORERS

# Imports inside functions stay there: gymnasium, numba, scipy, sim.episodes, trimesh,
# worlds.scene_dirs load on first use: `glmap` imports every command module to build its parser.

TASKS = ("objectnav", "instnav")
SPLITS = ("tune", "bench", "house-tune", "house-bench")  # = worlds.scene_dirs.BUILT_IN_SPLITS
EMBEDDERS = ("minilm", "hashing")
# Settings that change what one episode's result is; a results folder holds one set of them.
RESULT_KEYS = (
    "task",
    "split",
    "seed",
    "max_steps",
    "embedder",
    "scorer",
    "perception",
    "llm_model",
    "prompts",
)


def known_agents() -> tuple[str, ...]:
    """The agent names `agents.runner` can run."""

    return tuple(AGENTS)


def check_choice(name: str, value: str, choices: Sequence[str]) -> str:
    if value not in choices:
        raise InvalidInputError(
            f"unknown {name} {value!r}.{did_you_mean(value, choices)} "
            f"Choose from {', '.join(choices)}."
        )
    return value


def parse_agents(
    text: str | Sequence[str], choices: Sequence[str] | None = None
) -> tuple[str, ...]:
    """Agent names from 'a,b,c' (or a list), checked against `choices` (default: the runner's).

    Raises:
        InvalidInputError: an empty list, a repeated or an unknown name (with a did-you-mean).
    """
    names = [n.strip() for n in text.split(",")] if isinstance(text, str) else list(text)
    names = [n for n in names if n]
    if not names:
        raise InvalidInputError("no agents given; pass e.g. --agents glmap,egocentric,frontier.")
    choices = tuple(choices) if choices is not None else known_agents()
    for n in names:
        check_choice("agent", n, choices)
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise InvalidInputError(f"agents {repeated} are listed twice; list each agent once.")
    return tuple(names)


def episode_seed(seed: int, episode_id: str) -> int:
    """The seed of one episode: the same for every agent, so runs are paired."""
    return (seed * 1_000_003 + zlib.crc32(episode_id.encode("utf-8"))) % (2**31 - 1)


@functools.lru_cache(maxsize=64)
def _file_digest(path: str) -> str:
    return hashlib.sha1(Path(path).read_bytes()).hexdigest()


def episode_key(be: Any) -> str:
    """A digest of what a BenchEpisode is (start, goal, geodesic, scene layout file), so a
    resumed run notices results of benchmark files that were regenerated since."""
    e = be.episode
    what = [list(e.start_position), e.start_heading, e.goal_text, list(e.goal_object_ids)]
    text = json.dumps([*what, e.geodesic_distance, _file_digest(str(be.layout_path))])
    return hashlib.sha1(text.encode("utf-8")).hexdigest()[:16]


@dataclass(frozen=True)
class EvalSpec:
    """One evaluation: which episodes, which agents, and the settings of every episode.

    Attributes:
        task: 'objectnav' or 'instnav'.
        split: 'tune' (for choosing settings) or 'bench' (for reporting only), or the name
            of the scene folder `scenes_dir`.
        scenes: the first N scenes of the split (in scene-name order); None = all.
        episodes_per_scene: the first K episodes of each selected scene (file order);
            None = all.
        agents: agent names of `agents.runner.AGENTS`.
        seed: base seed; each episode's seed is `episode_seed(seed, episode_id)`.
        max_steps: actions before an episode is cut off (500 in the benchmark).
        embedder: the server's text embedder, 'minilm' or 'hashing'.
        scorer: f_S of the servers' value maps, 'embedding' (offline) or 'llm' (Ollama).
        perception: the simulator's perception, 'gt', 'detector' or 'auto' (the split's).
        llm_model: the Ollama model of the llm-tools agent or the llm scorer ('' when
            neither plays).
        prompts: the prompt set they used, as a digest of every prompt's name@hash.
        scenes_dir: a folder of one's own scenes (`glmap_tools.worlds.scene_dirs`) played as
            the split named `split`; None: a built-in split. Not a result setting: a moved
            folder resumes (each record's `episode_key` notices changed files).
    """

    task: str
    split: str
    scenes: int | None
    episodes_per_scene: int | None
    agents: tuple[str, ...]
    seed: int = 0
    max_steps: int = 500
    embedder: str = "minilm"
    scorer: str = "embedding"
    perception: str = "auto"
    llm_model: str = ""
    prompts: str = ""
    scenes_dir: Path | None = None

    def __post_init__(self) -> None:
        check_choice("task", self.task, TASKS)
        if self.scenes_dir is None:
            check_choice("split", self.split, SPLITS)
        else:
            from glmap_tools.worlds.scene_dirs import check_scene_dir, check_split_name

            check_split_name(self.split)
            object.__setattr__(self, "scenes_dir", check_scene_dir(Path(self.scenes_dir)))
        check_choice("embedder", self.embedder, EMBEDDERS)
        check_choice("scorer", self.scorer, SCORERS)
        check_choice("perception", self.perception, ("auto", "gt", "detector"))
        for name in ("scenes", "episodes_per_scene", "max_steps"):
            value = getattr(self, name)
            if value is None and name != "max_steps":
                continue
            if not isinstance(value, int) or value < 1:
                raise InvalidInputError(f"{name}={value!r} must be a positive integer.")
        if not self.agents:
            raise InvalidInputError("no agents given; pass e.g. --agents glmap,frontier.")

    @property
    def scene_dirs(self) -> dict[str, Path]:
        """{split: scenes_dir} for a scene folder, {} for a built-in split."""
        return {self.split: self.scenes_dir} if self.scenes_dir is not None else {}

    def result_config(self) -> dict[str, Any]:
        """The settings that decide an episode's result (stored beside the results)."""

        d = asdict(self)
        # The model settings only count when a model plays (older folders lack them).
        keys = [
            k
            for k in RESULT_KEYS
            if (k not in ("llm_model", "prompts") or d[k])
            and (k != "scorer" or d[k] != "embedding")
            and (k != "perception" or d[k] != "auto")
        ]
        return {**{k: d[k] for k in keys}, "image_size": AGENT_SIZE}


def select_episodes(
    task: str,
    split: str,
    scenes: int | None,
    per_scene: int | None,
    scene_dirs: dict[str, Path] | None = None,
) -> list[Any]:
    """The first `scenes` scenes of the split and the first `per_scene` episodes of each.

    `scene_dirs` (split name -> folder) names scene folders of one's own.

    Returns:
        BenchEpisodes ordered by scene name, then by their order in the split's files.

    Raises:
        InvalidInputError: the split has fewer scenes, or a chosen scene fewer episodes.
    """
    from glmap_tools.worlds.splits import load_split

    by_scene: dict[str, list[Any]] = {}
    for be in load_split(split, task, scene_dirs):
        by_scene.setdefault(be.scene, []).append(be)
    names = sorted(by_scene)
    scenes = len(names) if scenes is None else scenes
    if scenes > len(names):
        raise InvalidInputError(
            f"--scenes {scenes}: the {split} split has {len(names)} {task} scenes; "
            f"use --scenes {len(names)} or fewer."
        )
    chosen: list[Any] = []
    for name in names[:scenes]:
        episodes = by_scene[name]
        if per_scene is not None and per_scene > len(episodes):
            fewest = min(len(by_scene[n]) for n in names[:scenes])
            raise InvalidInputError(
                f"--episodes-per-scene {per_scene}: scene {name!r} of the {split} split has "
                f"{len(episodes)} {task} episodes; use {fewest} or fewer."
            )
        chosen.extend(episodes[:per_scene])
    return chosen
