"""`glmap eval sqa`: situated QA on the benchmark scenes — EM-1, EM-R1, localisation error.

Per scene (resumable: one JSON per scene in --out): build a GLMap from a tour with the
simulator's annotations (cached as `maps/<scene>.glmap`), generate the scene's situated QA
(`glmap_tools.worlds.qa`, seeded), and answer every question with each agent:

- glmap:       situate the text on the map (paper §3.2), answer at that pose;
- gt-pose:     answer at the ground-truth pose (the upper bound of the answerer);
- random-pose: answer at a random seen-free cell and heading (seeded);
- text-only:   no pose: unit descriptions only; directional questions get the map's most
               common label (a prior), the rest the same rules.

All four use the offline answerer (`glmap_tools.sqa.answer`), so the rows differ only in
where the agent thinks it stands. Means come with percentile-bootstrap 95% intervals over
questions, and paired differences against glmap.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import time
from collections import Counter
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools.atomic import write_atomic
from glmap_tools.checks import is_integer, is_real
from glmap_tools.errors import GLMapError, InvalidInputError, did_you_mean
from glmap_tools.eval.sqa_table import reading_ok, summarize, summarize_forms
from glmap_tools.orphans import exit_with_parent

# Imports inside functions stay there: cv2, gaussians, gymnasium, language.embed, numba, pyrender,
# scipy, sim.episodes, numba, tqdm, trimesh, worlds.scene_dirs load on first use: `glmap` imports
# every command module to build its parser.

SQA_AGENTS = ("glmap", "gt-pose", "random-pose", "text-only")


@dataclass(frozen=True)
class SqaSpec:
    """What one SQA evaluation runs (hashed: a rerun only mixes with the same spec)."""

    split: str = "tune"
    scenes: int | None = None
    situations: int = 8
    agents: tuple[str, ...] = SQA_AGENTS
    seed: int = 0
    embedder: str = "minilm"
    image: tuple[int, int] = (320, 240)
    tour_step: float = 0.5
    tour_spin: int = 8
    phrasings: bool = False  # many situation/question phrasings (glmap_tools.worlds.qa_phrasings)
    scenes_dir: Path | None = None  # a folder of one's own scenes played as `split`

    def key(self) -> str:
        data = asdict(self)
        data.pop("scenes")
        data.pop("scenes_dir")  # where the folder lies is not a setting (the name is)
        if not self.phrasings:
            data.pop("phrasings")  # keys of the runs before phrasings existed
        else:
            data["forms"] = 2  # with sqa.more_phrasings: not mixed with first-set-only runs
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:12]


def check_agents(names: Sequence[str]) -> tuple[str, ...]:
    for name in names:
        if name not in SQA_AGENTS:
            raise InvalidInputError(
                f"SQA agent {name!r} is not one of {list(SQA_AGENTS)}."
                f"{did_you_mean(name, SQA_AGENTS)}"
            )
    return tuple(names)


def _embedder(name: str) -> Any:
    from glmap_tools.language import embed, minilm

    return embed.HashingEmbedder() if name == "hashing" else minilm.default_embedder()


def scene_map(spec: SqaSpec, layout: Any, path: Path, embedder: Any) -> Any:
    """The scene's GLMap, built from a tour once and reopened from `path` afterwards."""
    from glmap_tools.map import GLMap, MapConfig
    from glmap_tools.sim.render import CameraSpec
    from glmap_tools.worlds.map_eval import build_map_from_tour

    if path.exists():
        return GLMap.open(path, embedder=embedder)
    tmp = path.with_name(path.name + ".building")
    tmp.unlink(missing_ok=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    glmap = GLMap.open(tmp, MapConfig(), embedder=embedder)
    try:
        camera = CameraSpec(width=spec.image[0], height=spec.image[1])
        build_map_from_tour(layout, glmap, camera, step=spec.tour_step, spin=spec.tour_spin)
    except BaseException:
        glmap.close()
        tmp.unlink(missing_ok=True)
        raise
    glmap.close()
    os.replace(tmp, path)
    return GLMap.open(path, embedder=embedder)


def _free_cells(glmap: Any) -> np.ndarray:
    from glmap_tools.map.occupancy import FREE

    occ = glmap.occupancy.to_dense()
    rows, cols = np.nonzero(occ.state == FREE)
    s = occ.cell_size
    return np.stack([(cols + occ.origin[0] + 0.5) * s, (rows + occ.origin[1] + 0.5) * s], 1)


def answer_scene(spec: SqaSpec, scene: str, layout_path: str, out: str) -> dict[str, Any]:
    """Build (or reopen) the scene's map and answer its questions with every agent."""
    from glmap_tools.sqa.answer import OfflineAnswerer, em1, em_r1
    from glmap_tools.worlds.qa import generate_qa
    from glmap_tools.worlds.splits import bench_layout

    t0 = time.perf_counter()
    layout = bench_layout(Path(layout_path))
    embedder = _embedder(spec.embedder)
    glmap = scene_map(spec, layout, Path(out) / "maps" / f"{scene}.glmap", embedder)
    build_s = time.perf_counter() - t0
    qa = generate_qa(layout, situations=spec.situations, seed=spec.seed, phrasings=spec.phrasings)
    if spec.phrasings:  # the second set of forms, at the same stand points
        from glmap_tools.sqa.more_phrasings import more_questions
        from glmap_tools.worlds.qa import situation_phrase

        qa["questions"] += more_questions(layout, qa, spec.seed, situation_phrase)
    rng = np.random.default_rng([spec.seed, int(hashlib.sha1(scene.encode()).hexdigest()[:8], 16)])
    free = _free_cells(glmap)
    prior = Counter(u.label for u in glmap.instances.values()).most_common(1)
    prior_label = prior[0][0] if prior else ""
    answerer = OfflineAnswerer()
    situated: dict[str, Any] = {}
    records = []
    for q in qa["questions"]:
        gt_xy = (q["position"]["_x"], q["position"]["_y"])
        gt_heading = float(q["heading"])
        answers = [a["answer"] for a in q["answers"]]
        for agent in spec.agents:
            t = time.perf_counter()
            pose, at, loc = _pose(agent, glmap, q, situated, free, rng)
            pred, supported, qtype = _answer(agent, glmap, q, pose, at, answerer, prior_label)
            forms = _form_fields(q, agent, qtype)
            records.append(
                {
                    **forms,
                    "scene": scene,
                    "question_id": q["question_id"],
                    "situation": q["situation"],
                    "stand": [round(gt_xy[0], 3), round(gt_xy[1], 3), round(gt_heading, 3)],
                    "type": q["question_type"],
                    "agent": agent,
                    "prediction": pred,
                    "answers": answers,
                    "em1": em1(pred, answers),
                    "em_r1": em_r1(pred, answers),
                    "supported": supported,
                    "seconds": round(time.perf_counter() - t, 4),
                    **loc,
                }
            )
    glmap.close()
    return {
        "scene": scene,
        "spec": spec.key(),
        "build_s": round(build_s, 2),
        "instances": None,
        "records": records,
    }


def _pose(
    agent: str,
    glmap: Any,
    q: dict[str, Any],
    situated: dict[str, Any],
    free: np.ndarray,
    rng: np.random.Generator,
) -> tuple[tuple[float, float, float] | None, Any, dict[str, Any]]:
    """(pose, the Situation the glmap agent answers at or None, localisation fields) of
    `agent` for question `q`: located from the situation text (glmap; `situated` caches
    each text's Situation or error), the true pose, a random free cell, or none."""
    from glmap_tools.sqa import situate

    gt_xy = (q["position"]["_x"], q["position"]["_y"])
    gt_heading = float(q["heading"])
    loc: dict[str, Any] = {}
    at: Any = None  # the Situation the glmap agent answers at
    if agent == "glmap":
        text = q["situation"]
        if text not in situated:
            try:
                situated[text] = situate(glmap, text)
            except GLMapError as exc:
                situated[text] = exc
        s = situated[text]
        if isinstance(s, GLMapError):
            pose = None
            loc = {"error": str(s)[:200]}
        else:
            pose = (s.x, s.y, s.heading)
            at = s
            err_m = math.hypot(s.x - gt_xy[0], s.y - gt_xy[1])
            err_deg = abs(math.degrees(math.remainder(s.heading - gt_heading, math.tau)))
            loc = {"err_m": round(err_m, 3), "err_deg": round(err_deg, 1)}
    elif agent == "gt-pose":
        pose = (gt_xy[0], gt_xy[1], gt_heading)
    elif agent == "random-pose":
        k = int(rng.integers(len(free))) if len(free) else 0
        xy = free[k] if len(free) else (0.0, 0.0)
        pose = (float(xy[0]), float(xy[1]), float(rng.uniform(-math.pi, math.pi)))
    else:
        pose = None
    return pose, at, loc


def _answer(
    agent: str,
    glmap: Any,
    q: dict[str, Any],
    pose: tuple[float, float, float] | None,
    at: Any,
    answerer: Any,
    prior_label: str,
) -> tuple[str, bool, str]:
    """(prediction, supported, question type read) of `agent` at `pose`: at the Situation
    (glmap), from the surroundings of the pose, or of the whole map (text-only)."""
    from glmap_tools.sqa.answer import answer_at
    from glmap_tools.sqa.surroundings import surroundings

    if pose is None and agent != "text-only":
        pred, supported, qtype = "", False, "unlocated"
    elif at is not None:  # excludes the anchor one stands at
        a, _ = answer_at(glmap, at, q["question"], answerer)
        pred, supported, qtype = a.answer, a.supported, a.question_type
    else:
        if agent == "text-only":
            where = surroundings(glmap, 0.0, 0.0, 0.0, radius=None, walls=False)
        else:
            assert pose is not None
            where = surroundings(glmap, pose[0], pose[1], pose[2])
        a = answerer.answer(q["question"], where)
        pred, supported, qtype = a.answer, a.supported, a.question_type
        if agent == "text-only" and qtype in ("left", "right", "front", "behind", "clock"):
            pred = prior_label  # no pose: the map's most common label
    return pred, supported, qtype


def _form_fields(q: dict[str, Any], agent: str, qtype: str) -> dict[str, Any]:
    """The phrasing fields of a record (none for a plain question)."""
    forms = {}
    if "question_form" in q:
        forms = {
            "situation_form": q["situation_form"],
            "question_form": q["question_form"],
            "held_out": q["held_out"],
            "round": q.get("round", 1),
            "read": qtype,
        }
        if agent == "glmap":
            forms["reading_ok"] = reading_ok(q["situation"], q["reading"])
    return forms


def run_sqa_eval(
    spec: SqaSpec, out: Path, *, workers: int = 2, progress: bool = True
) -> tuple[str, list[dict[str, Any]]]:
    """Run (or resume) the evaluation; write `scenes/*.json` and `summary.md`."""
    from tqdm import tqdm

    from glmap_tools.worlds.splits import split_dir

    check_agents(spec.agents)
    if spec.scenes_dir is not None:
        from glmap_tools.worlds.scene_dirs import check_scene_dir, scene_names

        folder = check_scene_dir(spec.scenes_dir)
        scenes = list(scene_names(folder))[: spec.scenes or None]
    else:
        folder = split_dir(spec.split)
        manifest = json.loads((folder / "split.json").read_text(encoding="utf-8"))
        scenes = [s["scene"] for s in manifest["scenes"]][: spec.scenes or None]
    (out / "scenes").mkdir(parents=True, exist_ok=True)
    todo, results = [], []
    for scene in scenes:
        path = out / "scenes" / f"{scene}.json"
        data = _stored_scene(path, scene)
        if data is not None:
            if data["spec"] != spec.key():
                raise InvalidInputError(
                    f"{path} was written with other settings (spec {data['spec']} vs "
                    f"{spec.key()}); use another --out."
                )
            results.append(data)
        else:
            todo.append(scene)
    layouts = {s: str(folder / s / "layout.json") for s in todo}
    bar = tqdm(total=len(todo), unit="scene", disable=not progress)

    def keep(data: dict[str, Any]) -> None:  # atomic: a killed run leaves no half a file
        path = out / "scenes" / f"{data['scene']}.json"
        write_atomic(path, [(json.dumps(data) + "\n").encode("utf-8")])
        results.append(data)
        bar.update(1)

    if workers <= 1 or len(todo) <= 1:
        for s in todo:
            keep(answer_scene(spec, s, layouts[s], str(out)))
    else:
        # Each pool process exits as soon as this one is gone (killed), instead of answering on.
        with ProcessPoolExecutor(max_workers=workers, initializer=exit_with_parent) as pool:
            futures = [pool.submit(answer_scene, spec, s, layouts[s], str(out)) for s in todo]
            for f in futures:
                keep(f.result())
    bar.close()
    records = [r for data in sorted(results, key=lambda d: d["scene"]) for r in data["records"]]
    table = summarize(records, spec.agents) + summarize_forms(records)
    for n, name in ((1, "first set (sim.qa_phrasings)"), (2, "second set (sqa.more_phrasings)")):
        part = [r for r in records if r.get("round") == n]
        if part and len(part) < len(records):  # each set on its own, with its intervals
            table += f"\n## The {name} alone\n\n" + summarize(part, spec.agents)
    head = (
        f"# SQA on {spec.split}: {len(scenes)} scenes, {spec.situations} situations each, "
        f"seed {spec.seed}, embedder {spec.embedder}\n\n"
    )
    (out / "summary.md").write_text(head + table, encoding="utf-8")
    return head + table, records


# The fields the tables read of each answer record: name -> kind; the optional ones may be
# absent, the forms (phrased questions) are in every record of a scene or in none.
_ANSWER_FIELDS = {
    "scene": str,
    "question_id": int,
    "situation": str,
    "type": str,
    "agent": str,
    "em1": bool,
    "supported": bool,
}
_OPTIONAL_ANSWER_FIELDS = {
    "stand": list,
    "err_m": float,
    "err_deg": float,
    "reading_ok": bool,
    "read": str,
    "round": int,
    "situation_form": str,
    "question_form": str,
}


def _is(value: Any, kind: type) -> bool:
    if kind is float:
        return is_real(value)
    if kind is int:
        return is_integer(value)
    return isinstance(value, kind)


def _stored_scene(path: Path, scene: str) -> dict[str, Any] | None:
    """A scene's stored answers, or None when there are none or the file is unreadable or
    not a scene's answers (the scene is then answered again)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("scene") != scene:
        return None
    records = data.get("records")
    if not isinstance(data.get("spec"), str) or not isinstance(records, list):
        return None
    forms = {isinstance(r, dict) and "situation_form" in r for r in records}
    for r in records:
        if not isinstance(r, dict) or r.get("scene") != scene or len(forms) > 1:
            return None
        for name, kind in _ANSWER_FIELDS.items():
            if not _is(r.get(name), kind):
                return None
        for name, kind in _OPTIONAL_ANSWER_FIELDS.items():
            if name in r and not _is(r[name], kind):
                return None
        if "situation_form" in r and not _is(r.get("question_form"), str):
            return None
        if ("err_m" in r) != ("err_deg" in r):
            return None
    return data


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--split", choices=["tune", "bench"], default="tune")
    p.add_argument(
        "--scenes-dir",
        metavar="[NAME=]DIR",
        help="a folder of one's own scenes (<scene>/layout.json) instead of --split",
    )
    p.add_argument("--scenes", type=int, default=None, help="the first N scenes")
    p.add_argument("--situations", type=int, default=8, help="situations per scene")
    p.add_argument("--agents", default=",".join(SQA_AGENTS), help="comma-separated")
    p.add_argument("--workers", type=int, default=2, help="processes (one scene each)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--out", type=Path, required=True, help="results folder (resumable)")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument(
        "--phrasings",
        action="store_true",
        help="situations and questions in many phrasings, with a per-form report",
    )


def run_cli(args: argparse.Namespace) -> int:
    split, folder = args.split, None
    if args.scenes_dir:
        from glmap_tools.worlds.scene_dirs import parse_scene_dir

        split, folder = parse_scene_dir(args.scenes_dir)
    spec = SqaSpec(
        split=split,
        scenes_dir=folder,
        scenes=args.scenes,
        situations=args.situations,
        agents=check_agents([a.strip() for a in args.agents.split(",") if a.strip()]),
        seed=args.seed,
        embedder=args.embedder,
        phrasings=args.phrasings,
    )
    text, records = run_sqa_eval(
        spec, args.out, workers=args.workers, progress=not args.no_progress
    )
    print(text)
    print(f"wrote {args.out / 'summary.md'} ({len(records)} answers)")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m glmap_tools.eval.sqa", description=__doc__)
    add_arguments(p)
    return run_cli(p.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
