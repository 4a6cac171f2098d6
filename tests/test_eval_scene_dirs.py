"""`glmap eval --scenes-dir`: a scan of one's own made into scenes, episodes with their
difficulty, played on a local worker process and tabled by difficulty bins.

The scenes are rotated rooms (27 and -40 deg about z, furniture in the room's frame)
converted by `glmap sim from-scan`; episodes come from `glmap sim episodes` (passage check
on); the step limit is 2, since the harness, not the agents, is under test.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from glmap_tools import cli
from glmap_tools.errors import InvalidInputError, UnknownIdError
from glmap_tools.eval import EvalSpec
from glmap_tools.eval.by_difficulty import episode_difficulties
from glmap_tools.server import ServerConfig
from glmap_tools.sim.episodes import load_episodes
from glmap_tools.sim.layout_io import load_layout
from glmap_tools.worlds.splits import bench_episode, load_split


def rotated_scan(yaw_deg: float, name: str) -> dict:
    """A 6 m x 4 m room turned by `yaw_deg` about z, with five boxes in its own frame."""
    yaw = math.radians(yaw_deg)
    rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])

    def world(x: float, y: float) -> list[float]:
        return [round(float(v), 4) for v in rot @ np.array([x, y])]

    objects = []
    for i, (cat, x, y, sx, sy, sz) in enumerate(
        [
            ("bed", 1.2, 1.5, 2.0, 1.6, 0.5),
            ("chair", 5.0, 3.0, 0.5, 0.5, 0.9),
            ("table", 4.5, 1.0, 1.2, 0.8, 0.75),
            ("sofa", 3.0, 3.5, 1.8, 0.8, 0.8),
            ("plant", 5.5, 0.4, 0.4, 0.4, 1.0),
        ],
        start=1,
    ):
        objects.append(
            {"id": i, "category": cat, "center": [*world(x, y), sz / 2], "size": [sx, sy, sz],
             "yaw": yaw}
        )  # fmt: skip
    polygon = [world(x, y) for x, y in [(0, 0), (6, 0), (6, 4), (0, 4)]]
    return {"up": "z", "name": name, "room": {"type": "bedroom", "polygon": polygon},
            "objects": objects}  # fmt: skip


TWO_ROOM_FURNITURE = [  # (room, category, x, y, width, depth, height) in the rooms' frame
    (1, "bed", 1.3, 1.2, 2.0, 1.6, 0.5),
    (1, "nightstand", 2.8, 0.4, 0.5, 0.4, 0.55),
    (2, "sofa", 6.5, 3.4, 1.8, 0.8, 0.8),
    (2, "table", 5.5, 1.3, 1.2, 0.8, 0.75),
    (2, "chair", 7.3, 1.3, 0.5, 0.5, 0.9),
]


def two_room_scan(yaw_deg: float = 27.0) -> dict:
    """Two rooms (4 m x 4 m and 4.5 m x 4 m, a 1 m opening in the wall they share) turned
    by `yaw_deg`, their furniture given as a scanner gives it: axis-aligned bounding boxes
    (yaw 0) of boxes that stand square to the walls."""
    yaw = math.radians(yaw_deg)
    rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])

    def world(x: float, y: float) -> list[float]:
        return [round(float(v), 4) for v in rot @ np.array([x, y])]

    c, s_ = abs(math.cos(yaw)), abs(math.sin(yaw))
    objects = [
        {"id": i, "category": cat, "center": [*world(x, y), h / 2],
         "size": [w * c + d * s_, w * s_ + d * c, h], "yaw": 0.0}
        for i, (_, cat, x, y, w, d, h) in enumerate(TWO_ROOM_FURNITURE, start=1)
    ]  # fmt: skip
    rooms = [
        {"type": "bedroom", "polygon": [world(x, y) for x, y in [(0, 0), (4, 0), (4, 4), (0, 4)]]},
        {"type": "living room",
         "polygon": [world(x, y) for x, y in [(4, 0), (8.5, 0), (8.5, 4), (4, 4)]]},
    ]  # fmt: skip
    openings = [{"id": 1, "rooms": [1, 2], "center": world(4.0, 2.0), "width": 1.0}]
    return {"up": "z", "name": "two-rooms", "rooms": rooms, "openings": openings,
            "objects": objects}  # fmt: skip


# First in the module: collected right after tests/test_eval_ray.py, whose Ray instance it
# then shares (`running_ray`).
@pytest.mark.slow  # 3 episodes on Ray (and the Ray start when first)
def test_a_local_ray_instance_plays_the_scene_folder_as_the_workers_do(
    running_ray: object, scenes: Path, tmp_path: Path
) -> None:
    from glmap_tools.eval.run import run_eval

    spec = EvalSpec(
        "objectnav", "mine", None, 1, ("frontier",), max_steps=4, embedder="hashing",
        scenes_dir=scenes,
    )  # fmt: skip
    on_ray = run_eval(spec, tmp_path / "ray", workers=1, ray_address="local", progress=False)
    here = run_eval(spec, tmp_path / "here", workers=0, progress=False)
    assert on_ray.failures == [] and on_ray.ran == 3  # one episode of each of the 3 scenes
    keys = ("success", "steps", "path_length", "collisions")
    for eid, record in on_ray.records["frontier"].items():
        assert {k: record[k] for k in keys} == {k: here.records["frontier"][eid][k] for k in keys}
    assert any("two-rooms" in eid for eid in on_ray.records["frontier"])


def test_a_turned_two_room_scan_of_bounding_boxes_becomes_rooms_with_furniture_square_to_them(
    tmp_path: Path,
) -> None:
    from glmap_tools.sim.layout import LayoutWarning
    from glmap_tools.worlds.scan import layout_from_scan

    with pytest.warns(LayoutWarning) as reported:
        layout = layout_from_scan(two_room_scan(27.0), use_meshes=False)
    said = [str(w.message) for w in reported]
    assert len(said) == len(TWO_ROOM_FURNITURE)  # every box is turned, and says so
    assert "read as a 2.00 x 1.60 m box turned 27.0 deg with the walls of room 1" in said[0]
    assert [r.type for r in layout.rooms] == ["bedroom", "living room"]
    for obj, (room, _, _, _, w, d, _) in zip(layout.objects, TWO_ROOM_FURNITURE, strict=True):
        assert obj.room == room
        np.testing.assert_allclose(obj.size[:2], [w, d], atol=1e-3)
    assert len(layout.openings) == 1


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("scans")
    folder = root / "my-scans"
    scans = {scene: rotated_scan(yaw, scene) for scene, yaw in (("a27", 27.0), ("b-40", -40.0))}
    scans["two-rooms"] = two_room_scan(27.0)
    for scene, data in scans.items():
        (folder / scene).mkdir(parents=True)
        scan = root / f"{scene}.json"
        scan.write_text(json.dumps(data), encoding="utf-8")
        layout = folder / scene / "layout.json"
        assert cli.main(["sim", "from-scan", str(scan), "--out", str(layout), "--boxes"]) == 0
        out = folder / scene / "objectnav.json"
        argv = ["sim", "episodes", str(layout), "--count", "3", "--seed", "1", "--out", str(out)]
        assert cli.main(argv) == 0
    return folder


def test_generated_episodes_carry_their_difficulty_and_pass_the_passage_check(
    scenes: Path,
) -> None:
    path = scenes / "a27"
    episodes = load_episodes(path / "objectnav.json", load_layout(path / "layout.json"))
    for e in episodes.episodes:
        d = e.difficulty
        assert d is not None
        assert d.geodesic_m == pytest.approx(e.geodesic_distance, abs=1e-3)
        assert d.passage_cells >= 3
        assert d.passage_m == pytest.approx(d.passage_cells * 0.05 + 0.36, abs=1e-3)


def test_a_file_without_difficulty_gets_it_measured_on_load(scenes: Path, tmp_path: Path) -> None:
    data = json.loads((scenes / "a27" / "objectnav.json").read_text(encoding="utf-8"))
    stored = [e.pop("difficulty") for e in data["episodes"]]
    bare = tmp_path / "bare"
    (bare / "a27").mkdir(parents=True)
    (bare / "a27" / "layout.json").write_text(
        (scenes / "a27" / "layout.json").read_text(encoding="utf-8"), encoding="utf-8"
    )
    (bare / "a27" / "objectnav.json").write_text(json.dumps(data), encoding="utf-8")
    selected = load_split("bare", "objectnav", {"bare": bare})
    assert all(be.episode.difficulty is None for be in selected)
    measured = episode_difficulties(selected)
    for be, d in zip(selected, stored, strict=True):
        assert measured[be.episode_id].passage_cells == d["passage_cells"]
        assert measured[be.episode_id].goal_in_sight == d["goal_in_sight"]


def test_a_scene_folder_episode_id_resolves_only_where_the_folder_is_given(scenes: Path) -> None:
    be = bench_episode("mine/objectnav/b-40-002", {"mine": scenes})
    assert be.scene == "b-40" and be.layout_path == scenes / "b-40" / "layout.json"
    with pytest.raises(UnknownIdError, match="--scenes-dir"):
        bench_episode("mine/objectnav/b-40-002")
    with pytest.raises(UnknownIdError, match="Did you mean 'mine/objectnav/b-40-002'"):
        bench_episode("mine/objectnav/b-40-02", {"mine": scenes})
    with pytest.raises(InvalidInputError, match="built-in split"):
        ServerConfig(scene_dirs={"tune": scenes})
    with pytest.raises(InvalidInputError, match="has no scene"):
        EvalSpec("objectnav", "x", None, None, ("random",), scenes_dir=scenes.parent)


def test_eval_plays_a_scene_folder_on_a_worker_and_splits_the_table_by_difficulty(
    scenes: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["eval", "objectnav", "--scenes-dir", f"mine={scenes}", "--out", str(out)]
    argv += ["--agents", "frontier,random", "--workers", "1", "--max-steps", "2"]
    argv += ["--embedder", "hashing", "--resamples", "200", "--no-progress", "--traces"]
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    assert "# objectnav on mine (" in printed and "## By difficulty" in printed
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["agents"]["frontier"]["episodes"] == 9
    assert summary["config"]["split"] == "mine"
    rows = {(r["dimension"], r["bin"]): r for r in summary["by_difficulty"]}
    assert sum(rows[("geodesic", b)]["episodes"] for b in ("< 5 m", "5-10 m", "> 10 m")) == 9
    assert (
        rows[("narrowest passage", ">= 0.7 m")]["episodes"]
        + rows[("narrowest passage", "< 0.7 m")]["episodes"]
        == 9
    )
    ids = sorted(p.stem for p in (out / "episodes").glob("*/*.json"))
    assert len(ids) == 18
    assert any((out / "traces").rglob("*")), "traces were asked for"
    # Resumable: the same command plays nothing again.
    assert cli.main(argv) == 0
    assert "played 0 episodes" in capsys.readouterr().out


@pytest.mark.slow  # builds one scene's map from a tour
def test_glmap_eval_sqa_answers_on_a_scene_folder(scenes: Path, tmp_path: Path) -> None:
    out = tmp_path / "sqa"
    argv = ["eval", "sqa", "--scenes-dir", f"mine={scenes}", "--scenes", "1"]
    argv += ["--situations", "2", "--agents", "glmap,text-only", "--workers", "1"]
    argv += ["--embedder", "hashing", "--no-progress", "--out", str(out)]
    assert cli.main(argv) == 0
    summary = (out / "summary.md").read_text(encoding="utf-8")
    assert summary.startswith("# SQA on mine: 1 scenes") and "| glmap |" in summary
    assert [p.stem for p in (out / "scenes").glob("*.json")] == ["a27"]


@pytest.mark.parametrize(
    ("file", "text", "match"),
    [
        ("split.json", "{bad", "split file .*split.json' is not valid JSON"),
        ("split.json", "[1]", "split.json is not a JSON object"),
        ("split.json", '{"scenes": [3]}', '"scenes" must list objects with a scene folder name'),
        ("split.json", '{"scenes": [{"x": 1}]}', '"scenes" must list objects with a scene'),
        ("a27/objectnav.json", "{bad", "episode file .*objectnav.json' is not valid JSON"),
        ("a27/objectnav.json", "null", "episode file format None version None"),
    ],
)
def test_a_broken_split_or_episode_file_in_a_scene_folder_is_refused_naming_it(
    scenes: Path, tmp_path: Path, file: str, text: str, match: str
) -> None:
    folder = tmp_path / "mine"
    (folder / "a27").mkdir(parents=True)
    for name in ("layout.json", "objectnav.json"):
        (folder / "a27" / name).write_bytes((scenes / "a27" / name).read_bytes())
    (folder / file).write_text(text, encoding="utf-8")
    with pytest.raises(InvalidInputError, match=match):
        load_split(
            "mine",
            "objectnav",
            {"mine": ServerConfig(scene_dirs={"mine": folder}).scene_dirs["mine"]},
        )
