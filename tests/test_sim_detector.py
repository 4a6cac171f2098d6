"""The simulator's detector-like perception: each rate of `data/detector_rates.json` holds
over many seeded draws of one real rendered view, draws are seeded per (scene, episode, view),
and region descriptions never name what is not in view."""

from __future__ import annotations

import math
import os
from dataclasses import replace

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.sim import detector as D
from glmap_tools.sim.annotate import annotate_view
from glmap_tools.sim.env import ObjectNavEnv
from glmap_tools.sim.layout import Layout
from glmap_tools.sim.render import CameraSpec

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
DRAWS = 1500


def within(observed: int, n: int, p: float, sigmas: float = 4.5) -> bool:
    """`observed` of `n` Bernoulli(p) draws lies within `sigmas` standard deviations."""
    sd = math.sqrt(max(n * p * (1 - p), 1e-9))
    return abs(observed - n * p) <= sigmas * sd + 1


@pytest.fixture(scope="module")
def view() -> dict:
    """One rendered view of a generated flat with several objects in sight."""
    env = ObjectNavEnv(scene_seed=3, camera=CameraSpec(160, 120), max_steps=50)
    env.reset(seed=1)
    best = None
    for action in [2] * 12:  # turn on the spot: keep the view with the most objects
        env.step(action)
        n = len(np.unique(env._view.instance_mask))
        if best is None or n > best[0]:
            pose = env.state.pose(env.camera.camera_height).matrix
            best = (n, env._view.instance_mask.copy(), env._view.depth.copy(), pose)
    env.close()
    _, mask, depth, pose = best
    return {
        "layout": env.layout,
        "mask": mask,
        "depth": depth,
        "pose": pose,
        "intrinsics": CameraSpec(160, 120).intrinsics,
    }


def detect(view: dict, episode: str, rates: D.DetectorRates, goal: str = "toilet"):
    return D.detect_view(
        view["mask"],
        view["depth"],
        view["layout"],
        view["intrinsics"],
        view["pose"],
        goal_category=goal,
        episode=episode,
        rates=rates,
    )


def quiet(rates: D.DetectorRates, **keep: float) -> D.DetectorRates:
    """`rates` with every error but those in `keep` switched off."""
    off = dict(
        recall_max=1.0,
        recall_half_pixels=0.0,
        recall_far_factor=1.0,
        recall_occluded_factor=1.0,
        confusion_base=0.0,
        confusion_small_extra=0.0,
        confusion_far_extra=0.0,
        false_positive_per_frame=0.0,
        mask_bleed_rate=0.0,
        wrong_color_rate=0.0,
    )
    off.update(keep)
    return replace(rates, **off)


def test_the_bundled_rates_load_and_a_bad_rate_is_refused_naming_it(tmp_path) -> None:
    rates = D.load_rates()
    assert 0 < rates.recall_max <= 1 and rates.group_of("sofa") and not rates.group_of("oven x")
    text = (tmp_path / "r.json").write_text('{"format": "glmap-detector-rates"}')
    assert text
    with pytest.raises(Exception, match="missing keys"):
        D.load_rates(tmp_path / "r.json")


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, "rates.json' does not exist; make one with a copy of the bundled"),
        (b"\xff\xfe{", "cannot read detector rates file .*utf-8"),
        (b"{not json", "is not valid JSON"),
        (b"[1, 2]", "is not a glmap-detector-rates file"),
    ],
)
def test_an_unreadable_rates_file_is_refused_naming_it(tmp_path, content, match) -> None:
    path = tmp_path / "rates.json"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(InvalidInputError, match=match):
        D.load_rates(path)


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("recall_max", "0.5", "recall_max=0.5 must be a number in"),
        ("recall_max", True, "recall_max=True must be a number"),
        ("recall_half_pixels", [], r"recall_half_pixels=\[\] must be a number"),
        ("recall_half_pixels", 10**400, "recall_half_pixels=1000000000.* must be a number in"),
        ("mask_bleed_pixels", {"a": 1}, "mask_bleed_pixels=.* must be a number"),
        ("confusion_groups", [["sofa", 3]], "confusion_groups must be lists of category names"),
        ("confusion_groups", "sofa", "confusion_groups must be lists of category names"),
    ],
    ids=["string", "bool", "list", "huge int", "dict", "group of a number", "groups a string"],
)
def test_a_rate_of_the_wrong_type_is_refused_naming_it(tmp_path, key, value, match) -> None:
    import json
    from importlib import resources

    data = json.loads((resources.files("glmap_tools") / "data" / "detector_rates.json").read_text())
    data[key] = value
    path = tmp_path / "rates.json"
    path.write_text(json.dumps(data))
    with pytest.raises(InvalidInputError, match=match):
        D.load_rates(path)


def test_recall_falls_with_apparent_size_distance_and_occlusion() -> None:
    rates = D.load_rates()
    full = D.recall(D.ObjectView(20_000, 1.0, 1.0), 640 * 480, rates)
    assert full == pytest.approx(rates.recall_max, abs=0.05)
    assert D.recall(D.ObjectView(1024, 1.0, 1.0), 640 * 480, rates) == pytest.approx(
        rates.recall_max / 2
    )  # half recall at the stated apparent size
    assert D.recall(D.ObjectView(20_000, 6.0, 1.0), 640 * 480, rates) < 0.7 * full
    assert D.recall(D.ObjectView(20_000, 1.0, 0.1), 640 * 480, rates) < 0.5 * full
    # The same view at a quarter of the pixels (a 320x240 image) has the same recall.
    assert D.recall(D.ObjectView(256, 1.0, 1.0), 320 * 240, rates) == pytest.approx(
        rates.recall_max / 2
    )


def test_measured_misses_match_each_objects_recall(view) -> None:
    rates = quiet(D.load_rates(), recall_max=0.8, recall_half_pixels=1024.0)
    ids = [int(i) for i in np.unique(view["mask"]) if i > 0]
    views = D.object_views(
        view["mask"], view["depth"], view["layout"], view["intrinsics"], view["pose"], ids
    )
    seen = dict.fromkeys(ids, 0)
    for k in range(DRAWS):
        _, ann = detect(view, f"e{k}", rates)
        for o in ann["objects"]:
            seen[o["id"]] += 1
    checked = 0
    for i in ids:
        if views[i].pixels < 4:  # below the sliver threshold: never detected
            assert seen[i] == 0
            continue
        p = D.recall(views[i], view["mask"].size, rates)
        assert within(seen[i], DRAWS, p), (i, seen[i] / DRAWS, p)
        checked += 1
    assert checked >= 3


def test_measured_confusions_match_the_rate_and_stay_in_the_group(view) -> None:
    rates = quiet(D.load_rates(), confusion_base=0.2)
    layout: Layout = view["layout"]
    ids = [int(i) for i in np.unique(view["mask"]) if i > 0]
    confusable = [i for i in ids if len(rates.group_of(layout.objects_by_id[i].category)) > 1]
    if not confusable:
        pytest.skip("no confusable category in this view")
    views = D.object_views(
        view["mask"], view["depth"], layout, view["intrinsics"], view["pose"], confusable
    )
    swapped = dict.fromkeys(confusable, 0)
    n = dict.fromkeys(confusable, 0)
    for k in range(DRAWS):
        _, ann = detect(view, f"c{k}", rates)
        for o in ann["objects"]:
            if o["id"] in swapped:
                true = layout.objects_by_id[o["id"]].category
                n[o["id"]] += 1
                if o["label"] != true:
                    assert o["label"] in rates.group_of(true)
                    assert o["label"] in o["description"]
                    swapped[o["id"]] += 1
    for i in confusable:
        difficulty = D.object_difficulty(layout, i, rates)
        p = D.confusion(views[i], view["mask"].size, difficulty, rates)
        assert within(swapped[i], n[i], p), (i, swapped[i] / n[i], p)


@pytest.mark.parametrize("look_alike_in_view", [True, False])
def test_measured_false_positives_per_frame_match_the_rate(view, look_alike_in_view) -> None:
    rates = quiet(D.load_rates(), false_positive_per_frame=0.1)
    layout: Layout = view["layout"]
    visible = {layout.objects_by_id[int(i)].category for i in np.unique(view["mask"]) if i > 0}
    groups = [g for g in rates.confusion_groups if set(g) & visible]
    if look_alike_in_view:  # a goal that something in view looks like
        goal = next(c for g in groups for c in g if c not in visible)
    else:
        goal = next(c for g in rates.confusion_groups if not set(g) & visible for c in g)
    frames_with_fp = on_object = 0
    for k in range(DRAWS):
        _, ann = detect(view, f"f{k}", rates, goal=goal)
        fps = [
            o
            for o in ann["objects"]
            if o["label"] == goal
            and (
                o["id"] not in layout.objects_by_id
                or layout.objects_by_id[o["id"]].category != goal
            )
        ]
        assert len(fps) <= 1
        frames_with_fp += bool(fps)
        if fps and fps[0]["id"] in layout.objects_by_id:
            on_object += 1
            assert goal in rates.group_of(layout.objects_by_id[fps[0]["id"]].category)
    share = rates.false_positive_on_object_share
    # A frame with nothing that looks like the goal gets only background false positives.
    p = 0.1 if look_alike_in_view else 0.1 * (1 - share)
    assert within(frames_with_fp, DRAWS, p)
    assert within(on_object, frames_with_fp, share if look_alike_in_view else 0.0)


def test_measured_wrong_colours_and_bleeding_masks_match_their_rates(view) -> None:
    rates = quiet(D.load_rates(), wrong_color_rate=0.1, mask_bleed_rate=0.3)
    layout: Layout = view["layout"]
    coloured = [
        int(i)
        for i in np.unique(view["mask"])
        if i > 0 and "color" in layout.objects_by_id[int(i)].attributes
    ]
    ids = [int(i) for i in np.unique(view["mask"]) if i > 0 and (view["mask"] == i).sum() >= 4]
    wrong = total = grown = masks = 0
    for k in range(DRAWS // 3):
        mask, ann = detect(view, f"w{k}", rates)
        for o in ann["objects"]:
            if o["id"] in coloured:
                total += 1
                wrong += o["description"] != layout.objects_by_id[o["id"]].text
        for i in ids:
            masks += 1
            grown += int((mask == i).sum() > (view["mask"] == i).sum())
    assert within(wrong, total, 0.1)
    # A bleed that finds no neighbour pixels to take leaves the mask as it was: at most.
    assert grown <= masks * 0.3 + 4.5 * math.sqrt(masks * 0.21) + 1
    assert grown >= masks * 0.3 * 0.5


def test_the_same_view_in_the_same_episode_gives_the_same_detections(view) -> None:
    rates = D.load_rates()
    a_mask, a = detect(view, "bench/objectnav/s00-001", rates)
    b_mask, b = detect(view, "bench/objectnav/s00-001", rates)
    assert a == b and np.array_equal(a_mask, b_mask)
    others = [detect(view, f"bench/objectnav/s00-{k:03d}", rates)[1] for k in range(2, 30)]
    assert any(o != a for o in others)  # another episode draws anew


def test_a_region_is_described_by_its_visible_members_only(view) -> None:
    layout: Layout = view["layout"]
    region = next(r for r in layout.regions if len(r.members) >= 2)
    keep = region.members[0]
    mask = np.zeros((40, 40), dtype=np.int32)
    mask[5:30, 5:30] = keep
    _, ann = annotate_view(mask, layout, min_pixels=4)
    (group,) = ann["groups"]
    seen = layout.objects_by_id[keep].category
    assert group["members"] == [keep]
    assert group["description"].startswith(f"{region.name}: ")
    hidden = {layout.objects_by_id[m].category for m in region.members[1:]} - {seen}
    for category in hidden:
        assert category not in group["description"], (category, group["description"])


def test_an_env_with_detector_perception_replays_identically_and_differs_from_gt() -> None:
    runs = []
    for perception in ("detector", "detector", "gt"):
        env = ObjectNavEnv(
            scene_seed=3, camera=CameraSpec(160, 120), max_steps=30, perception=perception
        )
        _, info = env.reset(seed=2)
        seen = [info["annotation"]]
        for action in [2, 2, 1, 3, 2, 2, 2, 1]:
            seen.append(env.step(action)[4]["annotation"])
        env.close()
        runs.append(seen)
    assert runs[0] == runs[1]
    assert runs[0] != runs[2]
    with pytest.raises(Exception, match="perception='yolo'"):
        ObjectNavEnv(scene_seed=3, camera=CameraSpec(160, 120), perception="yolo")
