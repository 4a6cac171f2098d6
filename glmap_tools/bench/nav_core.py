"""Benchmark the navigation core: per-step timings, FMM vs Dijkstra, stop-threshold calibration.

`python -m glmap_tools.bench nav-core [--repeat 30] [--steps 40]`

1. Nav part on a synthetic 20 m x 20 m apartment at 5 cm cells (400 x 400): FMM field
   from the agent, frontiers, the Eq. 7 value map of 150 instances + 30 regions, waypoint
   and plan; target <= 30 ms together.
2. FMM geodesic vs the Dijkstra-8 reference on the same map: the ratio over reachable
   cells >= 0.5 m from the agent must lie in [0.97, DIJKSTRA8_MAX_RATIO + 0.03].
3. Agent step in the simulator at 320x240 (first tune ObjectNav episode, policy 'glmap'):
   render (env.step) + integrate + decide, p50 <= 150 ms.

`python -m glmap_tools.bench nav-core --calibrate` builds a map from a tour of every tune
scene (seeds 1000+, never the bench split) and prints, per task, the precision and recall
of "instance score >= threshold" against the ground-truth goal objects, for several
thresholds and minimum observation counts (see nav/design.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from typing import Any

import numpy as np

from glmap_tools.bench._args import whole
from glmap_tools.bench._nav_loop import calibrate, closed_loop, run_episode
from glmap_tools.bench.report import Report
from glmap_tools.errors import InvalidInputError, did_you_mean
from glmap_tools.map.grid import IndexGrid
from glmap_tools.map.occupancy import FREE, OBSTACLE, UNKNOWN, DenseOccupancy
from glmap_tools.nav import DIJKSTRA8_MAX_RATIO, NavConfig, frontiers, reference_geodesic
from glmap_tools.nav.grid import plannable
from glmap_tools.nav.motion import clearance, masks
from glmap_tools.nav.planner import distance_field, plan_on_field
from glmap_tools.nav.value import value_map_from_scores
from glmap_tools.nav.waypoint import choose_waypoint
from glmap_tools.worlds.splits import load_split

CELL = 0.05


def synthetic_apartment(
    seed: int = 0, side_m: float = 20.0
) -> tuple[DenseOccupancy, IndexGrid, dict[int, float]]:
    """A side x side m floor: 5 m rooms with 1 m doors, furniture, an unknown top strip.

    Returns the occupancy, an index grid with 150 instances (the furniture) and 30 regions
    (five instances each), and a random score per unit.
    """
    rng = np.random.default_rng(seed)
    n = int(round(side_m / CELL))
    state = np.full((n, n), FREE, dtype=np.int8)
    for k in range(0, n + 1, n // 4):
        k = min(k, n - 2)
        state[k : k + 2, :] = OBSTACLE
        state[:, k : k + 2] = OBSTACLE
    for k in range(n // 8, n, n // 4):  # a door in the middle of every wall segment
        for w in range(0, n - 2, n // 4):
            if w > 0:
                state[k - 10 : k + 10, w : w + 2] = FREE
                state[w : w + 2, k - 10 : k + 10] = FREE
    grid = IndexGrid(CELL)
    scores: dict[int, float] = {}
    for uid in range(1, 151):
        r, c = rng.integers(4, n - 40, size=2)
        h, w = rng.integers(8, 30, size=2)
        state[r : r + h, c : c + w] = OBSTACLE
        grid.set_unit(uid, [(int(c + j), int(r + i)) for i in range(h) for j in range(w)])
        scores[uid] = float(rng.uniform(0.0, 1.0))
    for rid in range(151, 181):
        members = rng.choice(np.arange(1, 151), size=5, replace=False)
        cells = frozenset().union(*(grid.cells_of_unit(int(m)) for m in members))
        grid.set_unit(rid, cells)
        scores[rid] = float(rng.uniform(0.0, 1.0))
    state[int(0.9 * n) :, :] = UNKNOWN  # the unexplored top: frontiers along it
    return DenseOccupancy(state, (0, 0), CELL), grid, scores


def free_point(occ: DenseOccupancy, config: NavConfig, row: int, col: int) -> tuple[float, float]:
    """The plannable cell nearest (row, col), in world metres."""
    rows, cols = np.nonzero(plannable(occ, config.agent_radius) & (occ.state == FREE))
    k = int(np.argmin((rows - row) ** 2 + (cols - col) ** 2))
    return occ.index_to_world(int(rows[k]), int(cols[k]))


def time_nav_part(report: Report, repeat: int, stride: int) -> None:
    occ, grid, scores = synthetic_apartment()
    config = NavConfig(plan_stride=stride)
    agent = free_point(occ, config, 60, 60)
    rc = occ.world_to_index(*agent)
    parts: dict[str, list[float]] = {"fmm": [], "frontiers": [], "value map": [], "plan": []}
    wall = []
    for _ in range(repeat):
        w0 = time.perf_counter()
        t0 = time.process_time()
        clear = clearance(occ)
        trav, ok, speed = masks(occ, clear, rc, config)
        field = distance_field(occ, ok, rc, config.plan_stride, speed=speed)
        t1 = time.process_time()
        fronts = frontiers(
            occ, agent, config.agent_radius, config.min_frontier_size, field.metres, trav
        )
        t2 = time.process_time()
        value = value_map_from_scores(
            scores, grid, occ, config.value_sigma, unit_mass=config.unit_mass
        )
        t3 = time.process_time()
        wp = choose_waypoint(
            value, fronts, trav, agent, None, config, occ=occ, distance=field.metres
        )
        assert wp.xy is not None, "the synthetic apartment has frontiers"
        out = plan_on_field(occ, field, agent, 0.0, wp.xy, config, clear)
        t4 = time.process_time()
        wall.append((time.perf_counter() - w0) * 1000)
        for name, dt in zip(parts, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            parts[name].append(dt * 1000)
    total = np.sum([parts[k] for k in parts], axis=0)
    report.info(
        f"nav part, planning stride {stride} ({stride * CELL * 100:.0f} cm FMM cells), on "
        f"{occ.state.shape[1]} x {occ.state.shape[0]} map cells (20 m x 20 m at 5 cm), "
        f"{len(fronts)} frontiers, path {out.length:.1f} m, median CPU time of {repeat}: "
        + ", ".join(f"{k} {np.median(v):.1f} ms" for k, v in parts.items())
        + f"; wall time p50 {np.median(wall):.1f} ms at this load"
    )
    report.check(
        f"nav part CPU time p50, stride {stride} (fmm + frontiers + value map + plan)",
        float(np.median(total)),
        "<=",
        30.0,
        "ms",
    )


def fmm_vs_reference(report: Report, stride: int) -> None:
    """Dijkstra-8 / FMM over the reachable cells >= 0.5 m from the agent."""
    occ, _, _ = synthetic_apartment()
    config = NavConfig(plan_stride=stride)
    agent = free_point(occ, config, 60, 60)
    rc = occ.world_to_index(*agent)
    _, ok, speed = masks(occ, clearance(occ), rc, config)
    field = distance_field(occ, ok, rc, stride, speed=speed).metres
    ref = reference_geodesic(ok, rc, CELL, speed)
    # Blocks carry up to half a block of offset at the source: compare from 2 m out.
    near = 0.5 if stride == 1 else 2.0
    far = np.isfinite(ref) & np.isfinite(field) & (ref >= near)
    ratio = ref[far] / field[far]
    lost = int((np.isfinite(ref) & ~np.isfinite(field)).sum())
    report.info(
        f"stride {stride}: Dijkstra-8 / FMM over {int(far.sum())} cells >= {near} m away: min "
        f"{ratio.min():.4f}, median {np.median(ratio):.4f}, max {ratio.max():.4f}; cells "
        f"Dijkstra reaches and FMM does not: {lost} (8-connected paths overestimate straight "
        f"lines by up to {DIJKSTRA8_MAX_RATIO:.4f})"
    )
    slack = 0.03 if stride == 1 else 0.05  # a 10 cm block is 5 % of 2 m
    low, high = 1.0 - slack, DIJKSTRA8_MAX_RATIO + slack
    report.check(f"stride {stride}: Dijkstra-8 / FMM ratio, min", float(ratio.min()), ">=", low)
    report.check(f"stride {stride}: Dijkstra-8 / FMM ratio, max", float(ratio.max()), "<=", high)


def agent_step(report: Report, steps: int) -> None:
    """Time `steps` steps of policy 'glmap' on the first tune ObjectNav episode at 320x240.

    The check is on process CPU time (all threads): on an idle 2-core machine the wall time
    is at most that, and this machine is shared, so wall time is printed for reference.
    """
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

    be = load_split("tune", "objectnav")[0]
    result = run_episode(be, "glmap", max_steps=steps, timings=True)
    t = result["timings"]
    step = np.array(t["render"]) + np.array(t["integrate"]) + np.array(t["decide"])
    report.info(
        f"agent step on {be.episode_id} ({len(step)} steps, 320x240), CPU time p50: render "
        f"{np.median(t['render']):.1f} ms, integrate {np.median(t['integrate']):.1f} ms, "
        f"decide (value map + frontiers + plan) {np.median(t['decide']):.1f} ms; wall time "
        f"p50 {np.median(t['wall']):.1f} ms at this load"
    )
    report.check(
        "agent step CPU time p50 (render + integrate + value map + plan)",
        float(np.median(step)),
        "<=",
        150.0,
        "ms",
    )


def _indices(text: str) -> list[int]:
    """'0,25,50' or 'a:b:k' (range(a, b, k)) -> episode indices of the tune split."""
    if ":" in text:
        return list(range(*[int(v) for v in text.split(":")]))
    return [int(k) for k in text.split(",")]


def config_overrides(pairs: list[str]) -> dict[str, Any]:
    """NavConfig fields from FIELD=VALUE strings (JSON values; bare words are strings).

    Raises:
        InvalidInputError: an unknown field or a value NavConfig refuses.
    """

    fields = {f.name for f in dataclasses.fields(NavConfig)}
    out: dict[str, Any] = {}
    for pair in pairs:
        name, sep, text = pair.partition("=")
        if not sep or name not in fields:
            raise InvalidInputError(
                f"--set {pair!r}: give FIELD=VALUE with a NavConfig field."
                f"{did_you_mean(name, sorted(fields))}"
            )
        try:
            out[name] = json.loads(text)
        except ValueError:
            out[name] = text
    dataclasses.replace(NavConfig(), **out)  # refuses bad values now, not in a worker
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench nav-core")
    parser.add_argument("--repeat", type=whole(1, 10_000), default=30, help="timing repetitions")
    parser.add_argument(
        "--steps", type=whole(1, 100_000), default=40, help="simulator steps to time"
    )
    parser.add_argument("--no-sim", action="store_true", help="skip the simulator step")
    parser.add_argument("--calibrate", action="store_true", help="stop-threshold calibration")
    parser.add_argument(
        "--episodes", default="", help="closed loop on tune episodes instead: 0,25,50 or 0:100:4"
    )
    parser.add_argument("--task", default="objectnav", choices=("objectnav", "instnav"))
    parser.add_argument("--policies", default="glmap,frontier", help="comma-separated")
    parser.add_argument(
        "--workers", type=whole(1, 2), default=1, help="closed loop: processes (<= 2)"
    )
    parser.add_argument("--out", default=None, help="closed loop: per-episode JSON file")
    parser.add_argument(
        "--max-steps", type=whole(1, 100_000), default=500, help="closed loop: step limit"
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="closed loop: change a NavConfig field (repeatable), e.g. clearance_cost=2",
    )
    args = parser.parse_args(argv)
    if args.calibrate:
        return calibrate()
    if args.episodes:
        indices = _indices(args.episodes)
        policies = args.policies.split(",")
        overrides = config_overrides(args.set)
        return closed_loop(
            args.task, indices, policies, args.workers, args.out, args.max_steps, overrides
        )
    report = Report("bench nav-core")
    for stride in sorted({1, NavConfig().plan_stride}):
        time_nav_part(report, args.repeat, stride)
        fmm_vs_reference(report, stride)
    if not args.no_sim:
        agent_step(report, args.steps)
    return report.finish()


if __name__ == "__main__":
    raise SystemExit(main())
