"""Calibrate an embedder's text-similarity threshold tau_s on labelled description pairs.

Run: ``python -m glmap_tools.language.calibration [--embedder minilm|hashing]``.

The labelled set (`glmap_tools/data/tau_s_pairs.jsonl`) holds pairs of short object and
region descriptions, each with `same` (do they describe the same physical object/region?)
and a `kind`. Two instances merge when cos(phi(T_i), phi(T_j)) > tau_s AND their Gaussians
are mergeable; regions merge when the cosine passes AND they share an instance. The
geometric check separates two instances of one category that stand apart, but not
neighbours that touch (a pillow on a sofa, a chair at a table, a sink in a counter), nor
regions that share a boundary instance. So the threshold is chosen as the one with the best
recall over all same-object pairs while precision against the pairs that only text can
reject (kinds in `TEXT_ONLY_NEGATIVES`) is >= `TARGET_PRECISION`. Precision and recall
over the whole set are printed beside it.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.embed import Embedder, HashingEmbedder
from glmap_tools.language.minilm import default_embedder

TARGET_PRECISION = 0.90
TEXT_ONLY_NEGATIVES = frozenset({"different_category", "different_region"})
KINDS = (
    "same_paraphrase",
    "same_partial",
    "same_detail",
    "same_region",
    "different_instance",
    "different_category",
    "different_region",
)
THRESHOLDS = tuple(round(0.30 + 0.01 * i, 2) for i in range(66))  # 0.30 .. 0.95


@dataclass(frozen=True)
class Pair:
    """One labelled pair of descriptions."""

    a: str
    b: str
    same: bool
    kind: str


@dataclass(frozen=True)
class Scores:
    """Counts and rates of the rule `cos > threshold` on a set of pairs."""

    threshold: float
    tp: int
    fp: int
    fn: int
    tn: int
    text_only_fp: int  # false merges among TEXT_ONLY_NEGATIVES

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else 1.0

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else 0.0

    @property
    def f1(self) -> float:
        denom = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / denom if denom else 0.0

    @property
    def text_only_precision(self) -> float:
        """Precision counting only false merges that geometry cannot veto."""
        denom = self.tp + self.text_only_fp
        return self.tp / denom if denom else 1.0


def default_pairs_path() -> Path:
    """Path of the bundled labelled set."""
    return Path(str(resources.files("glmap_tools") / "data" / "tau_s_pairs.jsonl"))


def load_pairs(path: str | Path | None = None) -> list[Pair]:
    """Read labelled pairs from a JSON-lines file (default: the bundled set).

    Raises:
        InvalidInputError: a line that is not a pair with a, b, same, kind.
    """
    p = Path(path) if path is not None else default_pairs_path()
    pairs = []
    for number, line in enumerate(p.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
            pair = Pair(str(row["a"]), str(row["b"]), bool(row["same"]), str(row["kind"]))
        except (ValueError, KeyError, TypeError) as exc:
            raise InvalidInputError(
                f"{p}:{number}: expected a JSON object with a, b, same, kind; got {line[:80]!r}."
            ) from exc
        if pair.kind not in KINDS:
            raise InvalidInputError(f"{p}:{number}: kind={pair.kind!r} is not one of {KINDS}.")
        pairs.append(pair)
    return pairs


def pair_cosines(embedder: Embedder, pairs: Sequence[Pair]) -> np.ndarray:  # -> [P]
    """Cosine similarity of each pair's two descriptions under `embedder`."""
    texts = sorted({t for p in pairs for t in (p.a, p.b)})
    index = {t: i for i, t in enumerate(texts)}
    vectors = embedder.embed(texts)  # [T, dim], unit rows
    a = vectors[[index[p.a] for p in pairs]]
    b = vectors[[index[p.b] for p in pairs]]
    return np.einsum("pd,pd->p", a, b).astype(np.float32)


def score(cosines: np.ndarray, pairs: Sequence[Pair], threshold: float) -> Scores:
    """Confusion counts of `cos > threshold` against the labels."""
    merged = np.asarray(cosines) > threshold  # [P]
    same = np.array([p.same for p in pairs], dtype=bool)
    text_only = np.array([p.kind in TEXT_ONLY_NEGATIVES for p in pairs], dtype=bool)
    return Scores(
        threshold=float(threshold),
        tp=int((merged & same).sum()),
        fp=int((merged & ~same).sum()),
        fn=int((~merged & same).sum()),
        tn=int((~merged & ~same).sum()),
        text_only_fp=int((merged & text_only).sum()),
    )


def sweep(cosines: np.ndarray, pairs: Sequence[Pair]) -> list[Scores]:
    """Scores at every threshold of `THRESHOLDS`."""
    return [score(cosines, pairs, t) for t in THRESHOLDS]


def choose(table: Sequence[Scores]) -> tuple[Scores, str]:
    """Pick tau_s from a sweep: the best recall with text-only precision >= the target.

    Recall falls as the threshold rises, so that is the lowest threshold whose text-only
    precision reaches `TARGET_PRECISION`.

    Returns:
        (the chosen row, the rule that chose it). When no threshold reaches the target the
        row with the best F1 over the whole set is returned instead, and the rule says so.
    """
    rows = sorted(table, key=lambda s: s.threshold)
    for row in rows:
        if row.tp and row.text_only_precision >= TARGET_PRECISION:
            return row, f"best recall with text-only precision >= {TARGET_PRECISION}"
    best = max(rows, key=lambda s: (s.f1, s.threshold))
    return best, f"best F1 (no threshold reaches text-only precision {TARGET_PRECISION})"


def per_kind_rates(cosines: np.ndarray, pairs: Sequence[Pair], threshold: float) -> dict:
    """For each kind: (pairs, fraction merged at `threshold`)."""
    merged = np.asarray(cosines) > threshold
    out = {}
    for kind in KINDS:
        mask = np.array([p.kind == kind for p in pairs], dtype=bool)
        if mask.any():
            out[kind] = (int(mask.sum()), float(merged[mask].mean()))
    return out


def make_embedder(name: str) -> Embedder:
    """Build the embedder named on the command line."""
    if name == "minilm":
        return default_embedder()
    if name == "hashing":
        return HashingEmbedder()
    raise InvalidInputError(f"--embedder {name!r}: use 'minilm' or 'hashing'.")


def main(argv: Sequence[str] | None = None) -> int:
    """Print the threshold sweep and the chosen tau_s for one embedder."""
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.language.calibration", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--embedder", choices=("minilm", "hashing"), default="minilm")
    parser.add_argument("--pairs", default=None, help="JSON-lines labelled set (default: bundled)")
    args = parser.parse_args(argv)

    pairs = load_pairs(args.pairs)
    embedder = make_embedder(args.embedder)
    cosines = pair_cosines(embedder, pairs)
    table = sweep(cosines, pairs)
    chosen, rule = choose(table)

    n_same = sum(p.same for p in pairs)
    n_text_only = sum(p.kind in TEXT_ONLY_NEGATIVES for p in pairs)
    print(f"embedder {embedder.name}  declared default_tau_s {embedder.default_tau_s:.2f}")
    print(
        f"pairs {len(pairs)}: same {n_same}, different {len(pairs) - n_same} "
        f"(text-only negatives {n_text_only})"
    )
    print(" tau   prec  recall   F1   text-only-prec   tp   fp   fn   tn")
    for r in table:
        mark = "  <- chosen" if r.threshold == chosen.threshold else ""
        print(
            f"{r.threshold:.2f}  {r.precision:.3f}  {r.recall:.3f}  {r.f1:.3f}      "
            f"{r.text_only_precision:.3f}     {r.tp:4d} {r.fp:4d} {r.fn:4d} {r.tn:4d}{mark}"
        )
    print("\nmerge rate per kind at the chosen threshold (same_*: recall, different_*: FPR)")
    for kind, (count, rate) in per_kind_rates(cosines, pairs, chosen.threshold).items():
        print(f"  {kind:20s} n={count:4d}  merged {rate:.3f}")
    print(
        f"\nchosen tau_s = {chosen.threshold:.2f} ({rule}): precision {chosen.precision:.3f}, "
        f"recall {chosen.recall:.3f}, F1 {chosen.f1:.3f}, "
        f"text-only precision {chosen.text_only_precision:.3f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
