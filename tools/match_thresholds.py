"""Match thresholds per query kind on the labelled query set: the numbers behind
`glmap_tools.map.queries.REGION_TAU_MATCH` (issue 39).

    python tools/match_thresholds.py [--embedder minilm]

For each group of queries (instance or region queries; instance queries that ask for a use,
"somewhere to sit", or name a thing, "desk") it sweeps the top hit's score on the tuning half
with the rule of docs/search_quality.md (best top-hit recall at precision >= 0.9) and prints
the chosen threshold with its precision and recall on both halves, then the whole set under
the single threshold and under the rules tried.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any


def rates(rows: list[dict[str, Any]], t: Callable[[dict[str, Any]], float]) -> tuple[float, ...]:
    """(precision, recall, true, false, missed) of the top hits' match flags at threshold t(row)."""
    tp = fp = fn = 0
    for r in rows:
        flag = r["top"] is not None and r["top"] >= t(r)
        tp += flag and r["top_ok"]
        fp += flag and not r["top_ok"]
        fn += r["top_ok"] and not flag
    return (tp / (tp + fp) if tp + fp else 1.0), (tp / (tp + fn) if tp + fn else 0.0), tp, fp, fn


def calibrate(rows: list[dict[str, Any]]) -> float:
    """Best top-hit recall with precision >= 0.9, the highest such threshold on ties."""
    seen = sorted({round(r["top"], 4) for r in rows if r["top"] is not None})
    good = [(t, rates(rows, lambda _, t=t: t)) for t in seen]
    good = [(t, m) for t, m in good if m[0] >= 0.9]
    best = max(m[1] for _, m in good)
    return max(t for t, m in good if m[1] == best)


def main() -> None:
    from glmap_tools.language.calibration import make_embedder
    from glmap_tools.map.queries import MATCH_RULES, phrasings
    from glmap_tools.worlds import search_eval as se

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--embedder", choices=("minilm", "hashing"), default="minilm")
    args = parser.parse_args()
    embedder = make_embedder(args.embedder)
    rows = [
        {
            "split": o.query.split,
            "kind": o.query.kind,
            "use": len(phrasings(o.query.query)) > 1,
            "top": o.scores[0] if o.scores else None,
            "top_ok": bool(o.ranked and o.ranked[0] in o.query.answers),
        }
        for o in se.run_queries(se.load_queries(), embedder)
    ]
    tau = float(getattr(embedder, "default_tau_match", 0.5))
    declared = {"region": tau, "use": tau, "name": tau}
    RULES = MATCH_RULES.get(embedder.name, declared)  # noqa: N806
    groups: dict[str, Callable[[dict[str, Any]], bool]] = {
        "all": lambda r: True,
        "instance": lambda r: r["kind"] == "instance",
        "instance, asks for a use": lambda r: r["kind"] == "instance" and r["use"],
        "instance, names a thing": lambda r: r["kind"] == "instance" and not r["use"],
        "region": lambda r: r["kind"] == "region",
    }
    print(f"{embedder.name}: {len(rows)} queries; declared default_tau_match {tau}")
    chosen: dict[str, float] = {}
    for name, keep in groups.items():
        tune = [r for r in rows if r["split"] == "tune" and keep(r)]
        held = [r for r in rows if r["split"] == "held_out" and keep(r)]
        t = chosen[name] = calibrate(tune)
        p, rc, *_ = rates(tune, lambda _, t=t: t)
        hp, hr, *_ = rates(held, lambda _, t=t: t)
        dp, dr, *_ = rates(held, lambda _: tau)
        print(
            f"{name:26s} n {len(tune)}/{len(held)}  tau {t:.4f}: tune P {p:.3f} R {rc:.3f}, "
            f"held-out P {hp:.3f} R {hr:.3f}  (held-out at {tau}: P {dp:.3f} R {dr:.3f})"
        )
    rules: dict[str, Callable[[dict[str, Any]], float]] = {
        f"one threshold {tau}": lambda r: tau,
        "by unit kind (instance / region)": lambda r: (
            tau if r["kind"] == "instance" else chosen["region"]
        ),
        "by unit kind and use / name": lambda r: (
            chosen["region"]
            if r["kind"] == "region"
            else chosen["instance, asks for a use" if r["use"] else "instance, names a thing"]
        ),
        "declared (map.queries.MATCH_RULES)": lambda r: (
            RULES["region"] if r["kind"] == "region" else RULES["use" if r["use"] else "name"]
        ),
    }
    for name, rule in rules.items():
        line = []
        for split in ("tune", "held_out"):
            p, rc, tp, fp, fn = rates([r for r in rows if r["split"] == split], rule)
            line.append(f"{split} P {p:.3f} R {rc:.3f} ({tp}/{fp}/{fn})")
        print(f"{name:34s} " + "; ".join(line))


if __name__ == "__main__":
    main()
