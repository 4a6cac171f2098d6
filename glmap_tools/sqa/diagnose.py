"""Why a situation is mislocated: `python -m glmap_tools.sqa.diagnose --split tune`.

For every situation of a split's generated QA set, `situate()` on the scene's map is
compared with the ground-truth pose, and each miss gets one cause:

- ok:            within 1 m and 45 degrees (the localisation target);
- unlocated:     situate() raised (no match);
- wrong anchor:  the anchor unit that placed the agent is not the named object (its centre
                 is more than 0.5 m from the object's footprint), or a region placed it;
- wrong side:    right anchor, the pose more than 1 m off and not in front of the anchor;
- too far:       right anchor, in front of it, still more than 1 m off (a wide object);
- heading:       within 1 m, heading off by more than 45 degrees (wrong facing unit, or
                 the right one seen from a misplaced point).

Diagnostics only: the layout (ground truth) is read here to classify, never by situate().
Maps come from the `glmap eval sqa` cache (`--maps`), or are built from a tour there.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools.errors import GLMapError
from glmap_tools.eval.sqa import SqaSpec, _embedder, scene_map
from glmap_tools.sqa import situate
from glmap_tools.worlds.qa import generate_qa
from glmap_tools.worlds.splits import bench_layout, split_dir

NEAR_OBJECT = 0.5  # m: a unit whose centre is this close to an object's footprint is it


def _unit_centre(glmap: Any, unit_id: int | None) -> np.ndarray | None:
    if unit_id is None or unit_id not in glmap.instances:
        return None
    return np.asarray(glmap.instances[unit_id].gaussians.means[:, :2].mean(axis=0))


def classify(glmap: Any, layout: Any, q: dict[str, Any], s: Any) -> dict[str, Any]:
    """One situation's row: errors, the units that decided, and the cause of a miss."""
    gt = np.array([q["position"]["_x"], q["position"]["_y"]])
    anchor, facing = (layout.object(i) for i in q["object_ids"][:2])
    row: dict[str, Any] = {"situation": q["situation"], "anchor": anchor.category}
    if isinstance(s, GLMapError):
        return {**row, "cause": "unlocated", "error": str(s)[:120]}
    err_m = float(math.hypot(s.x - gt[0], s.y - gt[1]))
    err_deg = abs(math.degrees(math.remainder(s.heading - float(q["heading"]), math.tau)))
    a_c, f_c = _unit_centre(glmap, s.anchor_id), _unit_centre(glmap, s.facing_id)
    right_anchor = a_c is not None and float(anchor.distance_to(a_c)[0]) <= NEAR_OBJECT
    right_facing = f_c is not None and float(facing.distance_to(f_c)[0]) <= NEAR_OBJECT
    front = np.array([math.cos(anchor.heading), math.sin(anchor.heading)])
    ahead = float((np.array([s.x, s.y]) - anchor.position[:2]) @ front)
    if err_m <= 1.0 and err_deg <= 45.0:
        cause = "ok"
    elif not right_anchor:
        cause = "wrong anchor"
    elif err_m > 1.0:
        cause = "wrong side" if ahead <= anchor.size[1] / 2 else "too far"
    else:
        cause = "heading (wrong facing unit)" if not right_facing else "heading"
    return {
        **row,
        "cause": cause,
        "err_m": round(err_m, 2),
        "err_deg": round(err_deg, 1),
        "right_anchor": right_anchor,
        "right_facing": right_facing,
        "gt_distance": round(float(anchor.distance_to(gt)[0]), 2),
        "pose_distance": round(float(anchor.distance_to(np.array([s.x, s.y]))[0]), 2),
        "notes": s.notes,
    }


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m glmap_tools.sqa.diagnose", description=__doc__)
    p.add_argument("--split", choices=["tune", "bench"], default="tune")
    p.add_argument("--situations", type=int, default=8, help="situations per scene")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scenes", type=int, default=None, help="the first N scenes")
    p.add_argument("--maps", type=Path, required=True, help="map cache folder (<scene>.glmap)")
    p.add_argument("--json", type=Path, default=None, help="write every row here")
    p.add_argument(
        "--no-front-side", action="store_true", help="the earlier stand rule (for comparison)"
    )
    p.add_argument(
        "--no-sight",
        action="store_true",
        help="the closest anchor/facing pair without the line-of-sight filter (comparison)",
    )
    p.add_argument(
        "--no-relate",
        action="store_true",
        help="score the whole location/facing phrase, relations included (the earlier rule)",
    )
    p.add_argument(
        "--no-backrest",
        action="store_true",
        help="the stand side from the floor alone, no edge-height cue (the earlier rule)",
    )
    p.add_argument(
        "--phrasings",
        action="store_true",
        help="situations in many phrasings (glmap_tools.worlds.qa_phrasings); causes per form",
    )
    p.add_argument("--show", default="", help="print the rows with these causes (comma list)")
    return p


def diagnose_rows(args: argparse.Namespace) -> list[dict[str, Any]]:
    """One classified row per situation of the split's first scenes (`classify`)."""

    spec = SqaSpec(split=args.split, situations=args.situations, seed=args.seed)
    manifest = json.loads((split_dir(args.split) / "split.json").read_text(encoding="utf-8"))
    embedder = _embedder(spec.embedder)
    rows: list[dict[str, Any]] = []
    for entry in manifest["scenes"][: args.scenes or None]:
        scene = entry["scene"]
        layout = bench_layout(split_dir(args.split) / scene / "layout.json")
        glmap = scene_map(spec, layout, args.maps / f"{scene}.glmap", embedder)
        qa = generate_qa(
            layout, situations=args.situations, seed=args.seed, phrasings=args.phrasings
        )
        done = set()
        for q in qa["questions"]:
            if q["situation"] in done:
                continue
            done.add(q["situation"])
            try:
                s: Any = situate(
                    glmap,
                    q["situation"],
                    front_side=not args.no_front_side,
                    sight=not args.no_sight,
                    relate=not args.no_relate,
                    backrest=not args.no_backrest,
                )
            except GLMapError as exc:
                s = exc
            form = {"form": q["situation_form"]} if "situation_form" in q else {}
            rows.append({"scene": scene, **form, **classify(glmap, layout, q, s)})
        glmap.close()
    return rows


def _print_summary(rows: list[dict[str, Any]], args: argparse.Namespace) -> None:
    """Causes over all rows and per phrasing form; the rows asked for; the JSON file."""
    causes = Counter(r["cause"] for r in rows)
    n = len(rows)
    print(f"{args.split}: {n} situations; within 1 m and 45 deg: {causes['ok'] / max(n, 1):.3f}")
    for cause, k in causes.most_common():
        print(f"  {cause:28s} {k:3d}  {k / max(n, 1):.2f}")
    forms = sorted({r["form"] for r in rows if "form" in r})
    for f in forms:
        mine = [r for r in rows if r.get("form") == f]
        ok = sum(r["cause"] == "ok" for r in mine)
        print(f"  form {f:20s} {ok:3d} of {len(mine):3d} located")
    show = {c.strip() for c in args.show.split(",") if c.strip()}
    for r in rows:
        if r["cause"] in show:
            print(json.dumps(r))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    _print_summary(diagnose_rows(args), args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
