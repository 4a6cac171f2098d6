"""`python -m glmap_tools.bench sqa`: one situated question end to end, and localisation.

Builds (or reopens) the map of one benchmark scene from a tour, then for each situated
question of the scene's QA set times the whole offline pipeline: situate the text (p_r,
p_o -> H_r, H_o -> pose), render the four captioned views, list the surroundings, answer.
Prints the p50/p90 time per question (target <= 2 s on 2 cores) and the share of
situations located within 1 m and 45 degrees (target >= 0.7).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from glmap_tools.bench.report import Report
from glmap_tools.eval.sqa import SqaSpec, _embedder, scene_map
from glmap_tools.sqa import situate
from glmap_tools.sqa.answer import OfflineAnswerer, answer_at
from glmap_tools.sqa.views import labelled_views
from glmap_tools.worlds.qa import generate_qa
from glmap_tools.worlds.splits import bench_layout, split_dir


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m glmap_tools.bench sqa", description=__doc__)
    p.add_argument("--split", choices=["tune", "bench"], default="tune")
    p.add_argument("--scene", default="s00", help="scene of the split")
    p.add_argument("--situations", type=int, default=10)
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--cache", type=Path, default=Path("out/bench_sqa"), help="map cache folder")
    args = p.parse_args(argv)

    report = Report("bench sqa")
    spec = SqaSpec(split=args.split, situations=args.situations, embedder=args.embedder)
    layout = bench_layout(split_dir(args.split) / args.scene / "layout.json")
    t0 = time.perf_counter()
    glmap = scene_map(
        spec,
        layout,
        args.cache / f"{args.split}-{args.scene}-{args.embedder}.glmap",
        _embedder(args.embedder),
    )
    report.info(
        f"map of {args.split}/{args.scene}: {len(glmap.instances)} instances, "
        f"{len(glmap.regions)} regions (built or opened in {time.perf_counter() - t0:.1f} s)"
    )
    qa = generate_qa(layout, situations=args.situations, seed=spec.seed)
    times, located, seen = [], [], set()
    answerer = OfflineAnswerer()
    for q in qa["questions"]:
        t = time.perf_counter()
        s = situate(glmap, q["situation"])
        labelled_views(glmap, s.x, s.y, s.heading)
        answer_at(glmap, s, q["question"], answerer)
        times.append(time.perf_counter() - t)
        if q["situation"] not in seen:
            seen.add(q["situation"])
            err_m = math.hypot(s.x - q["position"]["_x"], s.y - q["position"]["_y"])
            err_deg = abs(math.degrees(math.remainder(s.heading - q["heading"], math.tau)))
            located.append(err_m <= 1.0 and err_deg <= 45.0)
    glmap.close()
    report.check("one question end to end, p50", float(np.median(times)), "<=", 2.0, "s")
    report.info(f"p90 {np.percentile(times, 90):.2f} s over {len(times)} questions")
    report.check(
        f"situations within 1 m and 45 deg ({len(located)})",
        float(np.mean(located)),
        ">=",
        0.7,
    )
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
