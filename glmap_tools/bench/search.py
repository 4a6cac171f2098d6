"""`python -m glmap_tools.bench search`: top-1, MRR and match precision/recall of text search.

Runs the labelled query set (glmap_tools/data/search_queries.jsonl) over maps built from the
simulator scenes' ground truth (see `glmap_tools.worlds.search_eval`), once with the plain
cosine ranking (before) and once through `GLMap.find_instances`/`find_regions` (after), and
prints both halves: the tuning half the ranking and the match threshold were chosen on, and
the held-out half (other scenes, other wordings).
"""

from __future__ import annotations

import argparse
import time

from glmap_tools.bench._args import existing_file
from glmap_tools.bench.report import Report
from glmap_tools.language.calibration import make_embedder
from glmap_tools.worlds import search_eval as se


def main(argv: list[str] | None = None) -> int:

    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.bench search",
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--embedder", choices=("minilm", "hashing"), default="minilm")
    parser.add_argument(
        "--queries",
        type=existing_file,
        default=None,
        help="JSON-lines query set (default: bundled)",
    )
    args = parser.parse_args(argv)

    report = Report("bench search")
    embedder = make_embedder(args.embedder)
    queries = se.load_queries(args.queries)
    start = time.perf_counter()
    maps: dict[int, se.SceneMap] = {}
    before = se.run_queries(queries, embedder, plain=True, maps=maps)
    after = se.run_queries(queries, embedder, maps=maps)
    seconds = time.perf_counter() - start
    tau = getattr(embedder, "default_tau_match", None)
    report.info(
        f"{len(queries)} queries over {len({q.scene for q in queries})} scenes, embedder "
        f"{embedder.name}, match threshold {tau}; ranked in {seconds:.1f} s"
    )
    for split, name in (("tune", "tuning half"), ("held_out", "held-out half")):
        b = se.metrics([o for o in before if o.query.split == split])
        m = se.metrics([o for o in after if o.query.split == split])
        report.info(
            f"{name}: {m.queries} queries, {m.answerable} with an answer; plain cosine "
            f"before: top-1 {b.top1:.3f}, MRR {b.mrr:.3f}"
        )
        report.check(f"top-1, {name}", m.top1, ">=", se.TARGET_TOP1)
        report.info(f"MRR, {name}: {m.mrr:.3f}")
        report.check(
            f"match precision (top hit), {name}", m.match_precision, ">=", se.TARGET_MATCH_PRECISION
        )
        report.check(
            f"match recall (top hit), {name}", m.match_recall, ">=", se.TARGET_MATCH_RECALL
        )
        report.info(
            f"match over the top {se.RETURNED} hits, {name}: precision {m.hit_precision:.3f}, "
            f"recall {m.hit_recall:.3f}; top-1 by phrasing: "
            + ", ".join(f"{k} {t:.2f} (n={n})" for k, (n, t) in m.by_phrasing.items())
        )
    return report.finish()
