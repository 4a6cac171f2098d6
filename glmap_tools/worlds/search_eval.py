"""Search quality of `find_instances`/`find_regions` on simulator scenes with known answers.

Run: ``python -m glmap_tools.bench search`` (prints figures against targets) or
``python -m glmap_tools.worlds.search_eval --calibrate`` (sweeps the match threshold).

The labelled queries (`glmap_tools/data/search_queries.jsonl`, built by
`glmap_tools.worlds.search_queries`) name a generated apartment and the layout ids of the
objects or regions that answer them. `scene_map` builds that apartment's GLMap from the
layout's ground truth: one instance unit per object (its category as label, its description
as text, Gaussians filling its box) and one region unit per region, exactly the units a
perfect perception would give a tour of the scene. Each query then runs through the library's
own `find` over every unit of its kind, and is scored:

- top-1: the best hit is one of the answers (answerable queries only);
- MRR: mean of 1 / rank of the first answer (0 when none ranks);
- match precision / recall on the top hit, the "is it in the map?" signal: of the queries
  whose best hit is flagged `match`, the share where it is an answer (precision; a flagged
  hit for a query nothing answers is a false match); of the queries whose best hit is an
  answer, the share where it is flagged (recall);
- the same per hit over the `RETURNED` hits a client sees (every flagged hit, every answer
  among them), printed beside it.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from glmap_tools.errors import InvalidInputError
from glmap_tools.gaussians.types import COVARIANCE_EPSILON, DEFAULT_OPACITY, GaussianSet
from glmap_tools.language.calibration import make_embedder
from glmap_tools.map import GLMap
from glmap_tools.map.units import InstanceUnit, RegionUnit
from glmap_tools.worlds.generator import generate_apartment
from glmap_tools.worlds.search_queries import default_queries_path

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder
    from glmap_tools.sim.layout import Layout

SPLITS = ("tune", "held_out")
GAUSSIANS_PER_OBJECT = 8
RETURNED = 5  # find_instance's default top_k
TARGET_TOP1 = 0.8
TARGET_MATCH_PRECISION = 0.9  # calibration rule: best top-hit recall at this precision
TARGET_MATCH_RECALL = 0.6


@dataclass(frozen=True)
class Query:
    """One labelled query (a line of the query set)."""

    id: str
    split: str
    scene: int
    kind: str
    query: str
    phrasing: str
    answers: tuple[int, ...]


@dataclass
class SceneMap:
    """A scene's map and the layout id behind each unit id."""

    glmap: GLMap
    layout_id: dict[int, int]  # unit id -> layout object id (instances) or region id


@dataclass
class Outcome:
    """One query's ranking over all units of its kind."""

    query: Query
    ranked: list[int]  # layout ids, best first
    scores: list[float]  # [same length] combined score of each hit
    matches: list[bool | None]  # [same length] the hit's match flag

    @property
    def rank(self) -> int | None:
        """1-based rank of the first answer, None when no answer is in the map."""
        for r, lid in enumerate(self.ranked, start=1):
            if lid in self.query.answers:
                return r
        return None


@dataclass
class Metrics:
    """Search quality of one split."""

    queries: int
    answerable: int
    top1: float
    mrr: float
    match_precision: float  # top hit
    match_recall: float  # top hit
    hit_precision: float  # every returned hit
    hit_recall: float  # every returned hit
    by_phrasing: dict[str, tuple[int, float]] = field(default_factory=dict)  # n, top-1


def load_queries(path: str | Path | None = None) -> list[Query]:
    """Read the labelled query set (default: the bundled one).

    Raises:
        InvalidInputError: a line that is not a query object with the fields above.
    """

    p = Path(path) if path is not None else default_queries_path()
    out = []
    for number, line in enumerate(p.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
            q = Query(
                str(row["id"]), str(row["split"]), int(row["scene"]), str(row["kind"]),
                str(row["query"]), str(row["phrasing"]), tuple(int(a) for a in row["answers"]),
            )  # fmt: skip
        except (ValueError, KeyError, TypeError) as exc:
            raise InvalidInputError(
                f"{p}:{number}: expected a JSON query with id, split, scene, kind, query, "
                f"phrasing, answers; got {line[:80]!r}."
            ) from exc
        if q.split not in SPLITS or q.kind not in ("instance", "region"):
            raise InvalidInputError(
                f"{p}:{number}: split {q.split!r}, kind {q.kind!r}: the split must be one "
                f"of {SPLITS} and the kind 'instance' or 'region'."
            )
        out.append(q)
    return out


def scene_map(layout: Layout, embedder: Embedder, seed: int = 0) -> SceneMap:
    """The GLMap a perfect perception would build of `layout` (see the module docstring)."""

    rng = np.random.default_rng(seed)
    texts = [o.text for o in layout.objects] + [r.description for r in layout.regions]
    vectors = dict(zip(texts, embedder.embed(texts), strict=True))
    g = GAUSSIANS_PER_OBJECT
    instances, layout_id = {}, {}
    for o in layout.objects:
        local = rng.uniform(-0.5, 0.5, size=(g, 3)) * o.size + [0.0, 0.0, 0.5 * o.size[2]]
        means = local @ o.rotation.T + o.position
        covs = np.tile(np.eye(3) * (1e-3 + COVARIANCE_EPSILON), (g, 1, 1))
        gaussians = GaussianSet(
            means, covs, np.full((g, 3), 0.5), np.full(g, DEFAULT_OPACITY), np.full(g, 10)
        )
        instances[o.id] = InstanceUnit(
            o.id, o.category, o.text, vectors[o.text], gaussians, 1, 0, 0
        )
        layout_id[o.id] = o.id
    next_id = max(instances, default=0) + 1
    regions = {}
    for r in layout.regions:
        regions[next_id] = RegionUnit(
            next_id, r.description, vectors[r.description], r.members, 1, 0, 0
        )
        layout_id[next_id] = r.id
        next_id += 1
    glmap = GLMap.from_units(instances, regions, next_id, embedder=embedder)
    return SceneMap(glmap, layout_id)


def run_queries(
    queries: Sequence[Query],
    embedder: Embedder,
    *,
    plain: bool = False,
    maps: dict[int, SceneMap] | None = None,
) -> list[Outcome]:
    """Rank every unit of each query's kind with the library's find (maps built per scene).

    Args:
        queries: labelled queries.
        embedder: the text embedder phi of the maps.
        plain: rank by the plain cosine between the query and each unit's description
            embedding instead (the ranking before phrasings and labels; no match flags).
        maps: scene maps by scene seed, filled as needed (pass one dict to reuse them).
    """

    maps = {} if maps is None else maps
    out = []
    for q in queries:
        if q.scene not in maps:
            maps[q.scene] = scene_map(generate_apartment(q.scene), embedder)
        sm = maps[q.scene]
        if plain:
            ids, matrix = (
                sm.glmap.instance_matrix() if q.kind == "instance" else sm.glmap.region_matrix()
            )
            scores = matrix @ embedder.embed([q.query])[0]
            order = np.lexsort((ids, -scores))
            ranked = [sm.layout_id[int(ids[i])] for i in order]
            out.append(Outcome(q, ranked, [float(scores[i]) for i in order], [None] * len(order)))
            continue
        n = len(sm.glmap.instances if q.kind == "instance" else sm.glmap.regions)
        find = sm.glmap.find_instances if q.kind == "instance" else sm.glmap.find_regions
        hits = find(q.query, k=n) if n else []
        out.append(
            Outcome(
                q,
                [sm.layout_id[h.id] for h in hits],
                [float(h.score or 0.0) for h in hits],
                [h.match for h in hits],
            )
        )
    return out


def match_counts(
    outcomes: Sequence[Outcome], threshold: float | None = None, hits: int = 1
) -> tuple[int, int, int]:
    """(true, false, missed) matches over the first `hits` hits of each query.

    Flags come from `threshold` when given, else from the hits' own `match`.
    """
    tp = fp = fn = 0
    for o in outcomes:
        for lid, s, m in list(zip(o.ranked, o.scores, o.matches, strict=True))[:hits]:
            flagged = bool(m) if threshold is None else s >= threshold
            answer = lid in o.query.answers
            tp += flagged and answer
            fp += flagged and not answer
            fn += answer and not flagged
    return tp, fp, fn


def _rates(counts: tuple[int, int, int]) -> tuple[float, float]:
    tp, fp, fn = counts
    return (tp / (tp + fp) if tp + fp else 1.0), (tp / (tp + fn) if tp + fn else 0.0)


def metrics(outcomes: Sequence[Outcome], threshold: float | None = None) -> Metrics:
    """Top-1, MRR and match precision/recall of a set of outcomes."""
    answerable = [o for o in outcomes if o.query.answers]
    ranks = [o.rank for o in answerable]
    top1 = float(np.mean([r == 1 for r in ranks])) if ranks else 0.0
    mrr = float(np.mean([1.0 / r if r else 0.0 for r in ranks])) if ranks else 0.0
    precision, recall = _rates(match_counts(outcomes, threshold, 1))
    hit_precision, hit_recall = _rates(match_counts(outcomes, threshold, RETURNED))
    by: dict[str, list[bool]] = {}
    for o in answerable:
        by.setdefault(o.query.phrasing, []).append(o.rank == 1)
    return Metrics(
        queries=len(outcomes),
        answerable=len(answerable),
        top1=top1,
        mrr=mrr,
        match_precision=precision,
        match_recall=recall,
        hit_precision=hit_precision,
        hit_recall=hit_recall,
        by_phrasing={k: (len(v), float(np.mean(v))) for k, v in sorted(by.items())},
    )


def calibrate(outcomes: Sequence[Outcome]) -> tuple[float, Metrics]:
    """The match threshold: best top-hit recall with precision >= TARGET_MATCH_PRECISION.

    Swept over every top-hit score seen (so no grid decides it); when no threshold reaches
    the precision, the one with the best F1 is returned.
    """
    rows = [
        (t, metrics(outcomes, t))
        for t in sorted({round(o.scores[0], 4) for o in outcomes if o.scores})
    ]
    good = [(t, m) for t, m in rows if m.match_precision >= TARGET_MATCH_PRECISION]
    if good:
        return max(good, key=lambda r: (r[1].match_recall, -r[0]))

    def f1(m: Metrics) -> float:
        return (
            2 * m.match_precision * m.match_recall / max(m.match_precision + m.match_recall, 1e-9)
        )

    return max(rows, key=lambda r: f1(r[1]))


def main(argv: Sequence[str] | None = None) -> int:
    """Print per-split quality; with --calibrate, sweep the match threshold on the tuning half."""
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.worlds.search_eval",
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--embedder", choices=("minilm", "hashing"), default="minilm")
    parser.add_argument("--queries", default=None, help="JSON-lines query set (default: bundled)")
    parser.add_argument("--calibrate", action="store_true", help="sweep the match threshold")
    parser.add_argument(
        "--failures", action="store_true", help="list queries whose top hit is wrong"
    )
    args = parser.parse_args(argv)

    embedder = make_embedder(args.embedder)
    queries = load_queries(args.queries)
    outcomes = run_queries(queries, embedder)
    for split in SPLITS:
        part = [o for o in outcomes if o.query.split == split]
        m = metrics(part)
        print(
            f"{split:9s} {m.queries} queries ({m.answerable} answerable): top-1 {m.top1:.3f}  "
            f"MRR {m.mrr:.3f}  match (top hit) precision {m.match_precision:.3f} recall "
            f"{m.match_recall:.3f}, (top {RETURNED}) {m.hit_precision:.3f} {m.hit_recall:.3f}"
        )
        print("   " + "  ".join(f"{k} {t:.2f} (n={n})" for k, (n, t) in m.by_phrasing.items()))
        if args.failures:
            for o in part:
                if o.query.answers and o.rank != 1:
                    top = o.ranked[:3]
                    print(
                        f"   x {o.query.id} scene {o.query.scene} {o.query.query!r}: top "
                        f"{top}, answers {list(o.query.answers)}, first answer at {o.rank}"
                    )
    if args.calibrate:
        tune = [o for o in outcomes if o.query.split == "tune"]
        t, m = calibrate(tune)
        held = metrics([o for o in outcomes if o.query.split == "held_out"], t)
        print(
            f"match threshold {t:.4f} (top hit, tuning half: precision {m.match_precision:.3f}, "
            f"recall {m.match_recall:.3f}; held-out: precision {held.match_precision:.3f}, "
            f"recall {held.match_recall:.3f})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
