"""`glmap sim ...`: make apartments, render tours, generate episodes and QA, run agents."""

from __future__ import annotations

import argparse
import json
import os
import time
import warnings
from pathlib import Path

from glmap_tools.errors import InvalidInputError

# Imports inside functions stay there: cv2, gaussians, gymnasium, language.embed, numba, pyrender,
# scipy, sim.episodes, numba, trimesh load on first use: `glmap` imports every command module to
# build its parser.


def _camera(args: argparse.Namespace):  # noqa: ANN202 - imported lazily
    from glmap_tools.sim.render import CameraSpec

    return CameraSpec(args.width, args.height, args.hfov, args.camera_height)


def _add_camera(p: argparse.ArgumentParser, width: int = 640, height: int = 480) -> None:
    p.add_argument("--width", type=int, default=width, help="image width (px)")
    p.add_argument("--height", type=int, default=height, help="image height (px)")
    p.add_argument("--hfov", type=float, default=79.0, help="horizontal field of view (deg)")
    p.add_argument("--camera-height", type=float, default=0.88, help="camera height (m)")


def _check_out(path: Path, overwrite: bool) -> None:
    if path.exists() and not overwrite:
        raise InvalidInputError(f"{str(path)!r} exists; pass --overwrite or choose another --out.")


def register(subparsers: argparse._SubParsersAction) -> None:
    sim = subparsers.add_parser(
        "sim",
        help="simulated apartments: layouts, tours, episodes, QA",
        description="Simulated apartments for ObjectNav, InstNav and situated QA (pyrender).",
    )
    sub = sim.add_subparsers(dest="sim_command", metavar="SIM_COMMAND")
    sim.set_defaults(func=lambda args: (sim.print_help(), 2)[1])
    _add_new(sub)
    _add_from_scan(sub)
    _add_tour(sub)
    _add_episodes(sub)
    _add_eval(sub)
    _add_map_eval(sub)
    _add_qa(sub)


def seed(text: str) -> int:
    """An argparse type: a non-negative integer seed (numpy's generators take no other)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a seed: give an integer >= 0")
    return value


def _add_new(sub: argparse._SubParsersAction) -> None:
    """`glmap sim new`."""
    p = sub.add_parser("new", help="generate a furnished apartment layout (JSON)")
    p.add_argument("--seed", type=seed, default=0, help="random seed (same seed, same layout)")
    p.add_argument(
        "--rooms", type=int, help="furnished rooms, 3..7 (houses 7..11; default: from the seed)"
    )
    p.add_argument(
        "--house",
        action="store_true",
        help="a house: 8-12 rooms along a hallway, two bedrooms and bathrooms at least, "
        "clutter, now and then a goal object in an unlikely room (the house splits')",
    )
    p.add_argument("--out", type=Path, required=True, help="layout JSON to write")
    p.add_argument("--topdown", type=Path, help="also write a top-down PNG of the layout")
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=run_new)


def _add_from_scan(sub: argparse._SubParsersAction) -> None:
    """`glmap sim from-scan`."""
    p = sub.add_parser("from-scan", help="convert a scan's object list (oriented boxes)")
    p.add_argument("scan", type=Path, help="JSON with 'objects': category, center, size, yaw")
    p.add_argument("--out", type=Path, required=True, help="layout JSON to write")
    p.add_argument("--up-axis", help="the scan world's up axis (default: its 'up' or z)")
    p.add_argument("--boxes", action="store_true", help="draw every object as a box")
    p.add_argument(
        "--aliases",
        type=Path,
        help='JSON {"scan label": "catalog category"} tried before the built-in aliases',
    )
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=run_from_scan)


def _add_tour(sub: argparse._SubParsersAction) -> None:
    """`glmap sim tour`."""
    p = sub.add_parser("tour", help="render a walk through every room into an RGB-D folder")
    p.add_argument("layout", type=Path, help="layout JSON")
    p.add_argument("--out", type=Path, required=True, help="folder to write")
    p.add_argument("--step", type=float, default=0.4, help="metres between walking frames")
    p.add_argument("--spin", type=int, default=8, help="headings looked at in each room")
    p.add_argument("--max-frames", type=int, help="stop after this many frames")
    p.add_argument(
        "--perception",
        choices=["gt", "detector"],
        default="gt",
        help="annotations: exact (gt) or with a detector's errors (sim/design.md)",
    )
    _add_camera(p)
    p.set_defaults(func=run_tour)


def _add_episodes(sub: argparse._SubParsersAction) -> None:
    """`glmap sim episodes`."""
    p = sub.add_parser("episodes", help="generate an ObjectNav or InstNav episode set")
    p.add_argument("layout", type=Path, help="layout JSON")
    p.add_argument("--task", choices=["objectnav", "instnav"], default="objectnav")
    p.add_argument("--count", type=int, default=50, help="number of episodes")
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--out", type=Path, required=True, help="episode JSON to write")
    p.add_argument("--overwrite", action="store_true")
    p.add_argument(
        "--min-passage-cells",
        type=int,
        default=3,
        help="draw starts only where the goal is reached through passages at least this many "
        "navigable cells wide (the bench split's check; default 3); 0 turns the check off",
    )
    p.add_argument(
        "--all-goals",
        action="store_true",
        help="also goals too small (< 0.15 m) or too high (bottom > 1.8 m) for the camera to "
        "recognise, which are left out (and listed) by default",
    )
    p.set_defaults(func=run_episodes)


def _add_eval(sub: argparse._SubParsersAction) -> None:
    """`glmap sim eval`."""
    p = sub.add_parser("eval", help="run the oracle or random agent on an episode set")
    p.add_argument("layout", type=Path, help="layout JSON")
    p.add_argument("episodes", type=Path, help="episode JSON (from `glmap sim episodes`)")
    p.add_argument("--agent", choices=["oracle", "random"], default="oracle")
    p.add_argument("--seed", type=seed, default=0, help="seed of the random agent")
    _add_camera(p, 160, 120)
    p.set_defaults(func=run_eval)


def _add_map_eval(sub: argparse._SubParsersAction) -> None:
    """`glmap sim map-eval`."""
    p = sub.add_parser(
        "map-eval", help="build a GLMap from a tour; instance precision/recall vs the layout"
    )
    p.add_argument("layout", type=Path, help="layout JSON")
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument(
        "--min-pixels", type=int, help="objects smaller in a frame are not annotated (default 64)"
    )
    p.add_argument("--step", type=float, default=0.4, help="metres between walking frames")
    p.add_argument("--spin", type=int, default=8, help="headings looked at in each room")
    p.add_argument("--max-frames", type=int, help="stop after this many frames")
    p.add_argument(
        "--perception",
        choices=["annotated", "geometric"],
        default="annotated",
        help="annotated: ground-truth masks; geometric: model-free segments named by "
        "ground truth (largest overlap), which measures the segmenter",
    )
    _add_camera(p)
    p.set_defaults(func=run_map_eval)


def _add_qa(sub: argparse._SubParsersAction) -> None:
    """`glmap sim qa`."""
    p = sub.add_parser("qa", help="generate a situated QA set (SQA3D-like JSON)")
    p.add_argument("layout", type=Path, help="layout JSON")
    p.add_argument("--situations", type=int, default=20)
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--out", type=Path, required=True, help="QA JSON to write")
    p.add_argument("--overwrite", action="store_true")
    p.add_argument(
        "--phrasings",
        action="store_true",
        help="situations and questions in many phrasings per family, the last of each "
        "held out (records say which)",
    )
    p.set_defaults(func=run_qa)


def run_new(args: argparse.Namespace) -> int:
    from glmap_tools.sim.layout_io import save_layout
    from glmap_tools.worlds.generator import generate_apartment

    _check_out(args.out, args.overwrite)
    layout = generate_apartment(args.seed, n_rooms=args.rooms, house=args.house)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_layout(layout, args.out)
    rooms = ", ".join(r.name for r in layout.rooms)
    print(
        f"wrote {args.out}: {len(layout.rooms)} rooms ({rooms}), {len(layout.objects)} objects, "
        f"{len(layout.regions)} regions"
    )
    if args.topdown:
        import cv2

        from glmap_tools.sim.navgrid import build_nav_grid
        from glmap_tools.sim.topdown import draw_topdown

        img = draw_topdown(layout, build_nav_grid(layout))
        cv2.imwrite(str(args.topdown), img[:, :, ::-1])
        print(f"wrote {args.topdown}")
    return 0


def run_from_scan(args: argparse.Namespace) -> int:

    from glmap_tools.sim.catalog import check_aliases
    from glmap_tools.sim.jsonfile import read_json
    from glmap_tools.sim.layout import LayoutWarning
    from glmap_tools.sim.layout_io import save_layout
    from glmap_tools.worlds.scan import category_shapes, layout_from_scan

    _check_out(args.out, args.overwrite)
    data = read_json(args.scan, "scan file", "a category + oriented-box list (see design.md)")
    aliases = None
    if args.aliases is not None:
        raw = read_json(args.aliases, "alias file", '{"scan label": "catalog category"}')
        aliases = check_aliases(raw, f"alias file {args.aliases.name!r}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LayoutWarning)
        layout = layout_from_scan(
            data, name=args.scan.stem, up=args.up_axis, use_meshes=not args.boxes, aliases=aliases
        )
    for w in caught:
        print(f"warning: {w.message}")
    args.out.parent.mkdir(parents=True, exist_ok=True)  # e.g. a new <scene>/ of a folder
    save_layout(layout, args.out)
    rooms = len(layout.rooms)
    print(f"wrote {args.out}: {len(layout.objects)} objects in {rooms} room{'s' * (rooms > 1)}")
    if not args.boxes:
        print("categories (scan -> drawn as):")
        for category, n, resolved, mesh in category_shapes(
            [o.category for o in layout.objects], aliases
        ):
            shape = f"{resolved} ({mesh})" if resolved is not None else "a plain box (unknown)"
            print(f"  {category} x{n} -> {shape}")
    return 0


def run_tour(args: argparse.Namespace) -> int:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from glmap_tools.sim.layout_io import load_layout
    from glmap_tools.worlds.tour import write_tour

    layout = load_layout(args.layout)
    n = write_tour(
        layout,
        args.out,
        _camera(args),
        args.step,
        args.spin,
        args.max_frames,
        perception=args.perception,
    )
    print(
        f"wrote {n} frames to {args.out} (color/, depth/, annotations/, trajectory.log, "
        f"camera_intrinsics.json); look at {args.out}/topdown.png and {args.out}/preview/"
    )
    return 0


def run_episodes(args: argparse.Namespace) -> int:
    from glmap_tools.sim.episodes import (
        MAX_PASSAGE_CELLS,
        generate_episodes,
        save_episodes,
        unseeable,
    )
    from glmap_tools.sim.layout_io import load_layout
    from glmap_tools.sim.navgrid import build_nav_grid
    from glmap_tools.worlds.difficulty import with_difficulty

    _check_out(args.out, args.overwrite)
    if not 0 <= args.min_passage_cells <= MAX_PASSAGE_CELLS:
        raise InvalidInputError(
            f"--min-passage-cells {args.min_passage_cells} must be 0 (no check) to "
            f"{MAX_PASSAGE_CELLS}."
        )
    layout = load_layout(args.layout)
    grid = build_nav_grid(layout)
    if not args.all_goals:
        for obj in layout.objects:
            why = unseeable(obj)
            if why is not None:
                print(f"left out as a goal: object {obj.id} {obj.category!r} ({why})")
    episodes = generate_episodes(
        layout,
        args.task,
        args.count,
        args.seed,
        grid,
        min_passage_cells=args.min_passage_cells,
        seeable_only=not args.all_goals,
    )
    episodes = with_difficulty(episodes, layout, grid)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_episodes(episodes, args.out)
    goals = len({e.goal_text for e in episodes.episodes})
    mean = sum(e.geodesic_distance for e in episodes.episodes) / len(episodes.episodes)
    print(
        f"wrote {args.out}: {len(episodes.episodes)} {args.task} episodes, {goals} distinct "
        f"goals, mean shortest path {mean:.2f} m"
    )
    return 0


def run_eval(args: argparse.Namespace) -> int:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    from glmap_tools.sim.agents import OracleAgent, RandomAgent, run_episodes, summarize
    from glmap_tools.sim.env import InstNavEnv, ObjectNavEnv
    from glmap_tools.sim.episodes import load_episodes
    from glmap_tools.sim.layout_io import load_layout

    layout = load_layout(args.layout)
    episodes = load_episodes(args.episodes, layout)
    env_cls = ObjectNavEnv if episodes.task == "objectnav" else InstNavEnv
    env = env_cls(layout=layout, episodes=episodes, camera=_camera(args))
    if args.agent == "oracle":
        results = run_episodes(env, OracleAgent)
    else:
        results = run_episodes(env, lambda e: RandomAgent(e, args.seed))
    env.close()
    s = summarize(results)
    print(
        f"{args.agent} agent on {int(s['episodes'])} {episodes.task} episodes: success "
        f"{s['success']:.1%}, SPL {s['spl']:.3f}, final distance to goal "
        f"{s['distance_to_goal']:.2f} m, {s['steps']:.1f} steps"
    )
    return 0


def run_map_eval(args: argparse.Namespace) -> int:
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

    from glmap_tools.language import embed, minilm
    from glmap_tools.map import GLMap
    from glmap_tools.sim.layout_io import load_layout
    from glmap_tools.worlds.map_eval import build_map_from_tour, evaluate_instances

    if args.min_pixels is not None and args.min_pixels < 1:
        raise InvalidInputError(f"--min-pixels {args.min_pixels} must be at least 1 pixel.")
    layout = load_layout(args.layout)
    embedder = embed.HashingEmbedder() if args.embedder == "hashing" else minilm.default_embedder()
    glmap = GLMap(embedder=embedder)
    start = time.perf_counter()
    seen = build_map_from_tour(
        layout,
        glmap,
        _camera(args),
        args.step,
        args.spin,
        args.max_frames,
        args.min_pixels,
        perception=args.perception,
    )
    result = evaluate_instances(glmap, layout, seen)
    print(
        f"{layout.name}: {len(glmap.trajectory)} frames in {time.perf_counter() - start:.0f} s; "
        f"{result.instances} map instances for {result.visible_objects} visible objects: "
        f"precision {result.precision:.3f}, recall {result.recall:.3f}"
    )
    if result.missed:
        print(
            "  missed objects: "
            + ", ".join(f"{i} {layout.object(i).category}" for i in result.missed)
        )
    if result.spurious:
        print(
            "  unmatched instances: "
            + ", ".join(f"{i} {glmap.instances[i].label}" for i in result.spurious)
        )
    n_dup = sum(len(v) for v in result.duplicate_instances.values())
    print(
        f"  duplicates: {n_dup} duplicate instances of {len(result.duplicate_instances)} "
        f"objects, {sum(len(g) - 1 for g in result.duplicate_regions)} duplicate regions "
        f"in {len(result.duplicate_regions)} groups (of {len(glmap.regions)} regions)"
    )
    for obj_id, extra in result.duplicate_instances.items():
        print(
            f"    object {obj_id} {layout.object(obj_id).category}: instances "
            + ", ".join(str(i) for i in extra)
            + " besides the matched one"
        )
    for group in result.duplicate_regions:
        print(f"    regions {', '.join(str(i) for i in group)}: shared members and description")
    return 0


def run_qa(args: argparse.Namespace) -> int:
    from glmap_tools.sim.layout_io import load_layout
    from glmap_tools.worlds.qa import generate_qa

    _check_out(args.out, args.overwrite)
    layout = load_layout(args.layout)
    qa = generate_qa(layout, args.situations, args.seed, phrasings=args.phrasings)
    args.out.write_text(json.dumps(qa, indent=1) + "\n", encoding="utf-8")
    n_sit = len({q["situation"] for q in qa["questions"]})
    print(f"wrote {args.out}: {len(qa['questions'])} questions in {n_sit} situations")
    return 0
