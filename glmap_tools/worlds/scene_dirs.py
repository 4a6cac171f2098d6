"""Scene folders of one's own, played like a benchmark split: named, with stable episode ids.

A scene folder holds one folder per scene, each with `layout.json` (`layout_io`) and the
episode files of the tasks it is played on (`objectnav.json`, `instnav.json`: `episodes.py`
episode sets), the layout of the built-in splits under `glmap_tools/data/benchmark/<split>/`.
A `split.json` beside the scenes is optional; when present, its "scenes" list
(`[{"scene": "s00", ...}]`) chooses and orders them, otherwise every sub-folder with a
`layout.json` is a scene, in name order.

A folder is given a name (`NAME=DIR`, or the folder's own name), and its episodes get the ids
`<name>/<task>/<scene>-<index>` (e.g. `mine/objectnav/kitchen-003`). The name travels with
the folder to whoever resolves those ids: `ServerConfig.scene_dirs` (`glmap-mcp --scenes-dir`)
on a server, `EvalSpec.scenes_dir` on `glmap eval` and its workers.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glmap_tools.errors import InvalidInputError, UnknownIdError, did_you_mean
from glmap_tools.sim.episodes import TASKS, Episode, episodes_from_dict
from glmap_tools.sim.jsonfile import read_json

BUILT_IN_SPLITS = ("tune", "bench", "house-tune", "house-bench")
NAME_PATTERN = re.compile(r"^[a-z0-9][a-z0-9_-]{0,23}$")
SceneDirs = Mapping[str, Path]  # split name -> scene folder
PERCEPTIONS = ("gt", "detector")


@dataclass(frozen=True)
class BenchEpisode:
    """One episode of a split (built-in or a scene folder) and where its scene lives.

    Attributes:
        episode_id: "<split>/<task>/<scene>-<index>", e.g. "bench/objectnav/s03-017".
        task: "objectnav" or "instnav".
        split: "tune", "bench", "house-tune", "house-bench", or a scene folder's name.
        scene: the scene's folder in the split ("s03"); the layout itself has its own name
            (e.g. "apartment-<seed>").
        layout_path: the scene's layout JSON.
        episode: the episode (start, heading, goal text and object ids, geodesic metres,
            difficulty when the file has it).
        perception: the perception the split is played with by default: its `split.json`'s
            "perception" ("detector" for the house splits), else "gt".
    """

    episode_id: str
    task: str
    split: str
    scene: str
    layout_path: Path
    episode: Episode
    perception: str = "gt"


def check_split_name(name: str) -> str:
    """`name` when it may name a scene folder: 1-24 of a-z, 0-9, '_' and '-', not a
    built-in split's name.

    Raises:
        InvalidInputError: a name of another form, or a built-in split's.
    """
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise InvalidInputError(
            f"scene folder name {name!r} must be 1-24 characters of a-z, 0-9, '_' and '-', "
            "starting with a letter or digit; give one as NAME=DIR."
        )
    if name in BUILT_IN_SPLITS:
        raise InvalidInputError(
            f"scene folder name {name!r} is a built-in split's; give another as NAME=DIR."
        )
    return name


def default_name(folder: Path) -> str:
    """The name a folder gets when none is given: its own name, lower case, other
    characters as '-' (e.g. 'My Scans' -> 'my-scans')."""
    name = re.sub(r"[^a-z0-9_-]+", "-", Path(folder).resolve().name.lower()).strip("-_")
    return name[:24] or "scenes"


def parse_scene_dir(text: str) -> tuple[str, Path]:
    """(name, folder) of 'NAME=DIR' or 'DIR' (named after the folder), the folder checked.

    Raises:
        InvalidInputError: a bad name, a missing folder or one without scenes.
    """
    name, sep, rest = str(text).partition("=")
    if sep and NAME_PATTERN.match(name):
        folder = Path(rest).expanduser()
    else:
        name, folder = "", Path(text).expanduser()
    folder = check_scene_dir(folder)
    return check_split_name(name or default_name(folder)), folder


def check_scene_dirs(dirs: SceneDirs | Iterable[tuple[str, Path]]) -> dict[str, Path]:
    """{name: absolute folder} with every name and folder checked."""
    items = dirs.items() if isinstance(dirs, Mapping) else dirs
    return {check_split_name(n): check_scene_dir(Path(f)) for n, f in items}


def check_scene_dir(folder: Path) -> Path:
    """The folder, absolute, when it holds at least one scene (`<scene>/layout.json`).

    Raises:
        InvalidInputError: no such folder, or no scene in it.
    """
    folder = Path(folder).expanduser().resolve()
    if not folder.is_dir():
        raise InvalidInputError(
            f"scene folder {folder} does not exist; give a folder of <scene>/layout.json "
            "and <scene>/<task>.json (docs/evaluation.md, Your own scenes)."
        )
    if not scene_names(folder):
        raise InvalidInputError(
            f"scene folder {folder} has no scene: no sub-folder with a layout.json in it "
            "(docs/evaluation.md, Your own scenes)."
        )
    return folder


def _split_manifest(folder: Path) -> dict[str, Any]:
    manifest = folder / "split.json"
    if not manifest.is_file():
        return {}
    data = read_json(manifest, "split file", "a JSON object (docs/evaluation.md, Your own scenes)")
    if not isinstance(data, dict):
        raise InvalidInputError(
            f'{manifest} is not a JSON object; write {{"scenes": [{{"scene": "s00"}}]}}, or '
            "remove it to play every <scene>/layout.json."
        )
    scenes = data.get("scenes")
    if scenes is not None and not (
        isinstance(scenes, list)
        and all(isinstance(s, dict) and isinstance(s.get("scene"), str) for s in scenes)
    ):
        raise InvalidInputError(
            f'{manifest}: "scenes" must list objects with a scene folder name, e.g. '
            f'[{{"scene": "s00"}}], got {str(scenes)[:80]}.'
        )
    return data


def scene_names(folder: Path) -> tuple[str, ...]:
    """The folder's scenes: split.json's "scenes" when it has them, else every sub-folder
    with a layout.json, in name order."""
    data = _split_manifest(folder)
    if isinstance(data.get("scenes"), list):
        return tuple(str(s["scene"]) for s in data["scenes"])
    return tuple(sorted(p.parent.name for p in folder.glob("*/layout.json")))


def split_perception_of(folder: Path) -> str:
    """The perception a split folder is played with by default: its `split.json`'s
    "perception" ("gt" or "detector"), "gt" where it names none.

    Raises:
        InvalidInputError: a "perception" other than "gt" or "detector".
    """
    perception = _split_manifest(folder).get("perception", "gt")
    if perception not in PERCEPTIONS:
        raise InvalidInputError(
            f"{folder / 'split.json'}: perception {perception!r} is not one of {PERCEPTIONS}; "
            'write "gt" or "detector", or leave it out (gt).'
        )
    return str(perception)


@functools.lru_cache(maxsize=32)
def read_scene_episodes(
    folder: Path, split: str, task: str, scenes: tuple[str, ...]
) -> tuple[BenchEpisode, ...]:
    """Every `task` episode of `scenes` under `folder`, as episodes of split `split`
    (scene order, then file order); a scene without a `<task>.json` has none."""
    out = []
    perception = split_perception_of(folder)
    for scene in scenes:
        path = folder / scene / f"{task}.json"
        if not path.is_file():
            continue
        data = read_json(path, "episode file", "`glmap sim episodes`")
        for e in episodes_from_dict(data).episodes:
            out.append(
                BenchEpisode(
                    episode_id=f"{split}/{task}/{scene}-{e.episode_id:03d}",
                    task=task,
                    split=split,
                    scene=scene,
                    layout_path=folder / scene / "layout.json",
                    episode=e,
                    perception=perception,
                )
            )
    return tuple(out)


def scene_dir_episodes(name: str, folder: Path, task: str) -> tuple[BenchEpisode, ...]:
    """Every `task` episode of the scene folder named `name`.

    Raises:
        InvalidInputError: no scene of the folder has a `<task>.json`.
    """
    folder = Path(folder)
    found = read_scene_episodes(folder, name, task, scene_names(folder))
    if not found:
        raise InvalidInputError(
            f"scene folder {folder} ({name!r}) has no {task} episodes: no <scene>/{task}.json; "
            f"make them with `glmap sim episodes <scene>/layout.json --task {task} --out "
            f"<scene>/{task}.json`."
        )
    return found


def scene_dir_episode(episode_id: str, dirs: SceneDirs) -> BenchEpisode:
    """The episode with this id in one of the named scene folders.

    Raises:
        UnknownIdError: the id names no folder of `dirs`, or no episode of it.
    """
    split, _, rest = str(episode_id).partition("/")
    task = rest.partition("/")[0]
    if split not in dirs or task not in TASKS:
        names = [*BUILT_IN_SPLITS, *dirs]
        raise UnknownIdError(
            f"episode id {episode_id!r} is not '<split>/<task>/<scene>-<index>' with split in "
            f"{names} and task in {TASKS}.{did_you_mean(split, names)} A scene folder's "
            "episodes need the folder given to the server (glmap-mcp --scenes-dir NAME=DIR)."
        )
    episodes = {be.episode_id: be for be in scene_dir_episodes(split, dirs[split], task)}
    if episode_id not in episodes:
        raise UnknownIdError(
            f"no episode {episode_id!r} in scene folder {dirs[split]}."
            f"{did_you_mean(episode_id, episodes)} {split}/{task} has {len(episodes)} episodes."
        )
    return episodes[episode_id]
