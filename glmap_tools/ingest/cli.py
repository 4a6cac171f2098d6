"""`glmap build`: build a GLMap file from a Redwood- or TUM-style RGB-D folder."""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from glmap_tools.errors import InvalidInputError
from glmap_tools.ingest.batch import build_many
from glmap_tools.ingest.build import EMBEDDERS, PERCEPTIONS, BuildSettings, build_map
from glmap_tools.ingest.scans import is_sequence
from glmap_tools.ingest.summary import SUMMARY_NAME, cpu_per_frame, format_table
from glmap_tools.language.backends import add_llm_arguments, settings_from_args

if TYPE_CHECKING:
    from glmap_tools.ingest.build import BuildStats
    from glmap_tools.ingest.datasets import RGBDSequence
    from glmap_tools.map import GLMap

# Imports inside functions stay there: tqdm load on first use: `glmap` imports every command module
# to build its parser.

BUNDLED = "redwood_livingroom1_5frames"
DEFAULT_OUT = Path("out/redwood.glmap")


def bundled_folder() -> Path:
    """The five real Redwood living-room frames shipped with the package."""
    return Path(str(resources.files("glmap_tools") / "data" / BUNDLED))


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "build",
        help="build a map file from an RGB-D folder, or one per folder of many",
        description=(
            "Build a GLMap from a Redwood-style (color/, depth/, trajectory.log, intrinsics "
            "JSON) or TUM-style (rgb.txt, depth.txt, groundtruth.txt) folder. Frames with "
            "annotations/<stem>.png + .json give instances and regions; others update "
            "occupancy only. Without FOLDER, builds the bundled Redwood frames.\n\n"
            "Many scans: FOLDER may instead hold scan folders, or be a text file listing "
            "them ([NAME=]FOLDER a line); --out is then a folder that gets <scan>.glmap per "
            "scan. Maps that exist are skipped (resumable), --workers builds N at once, "
            "--ray-address builds on a Ray cluster. See docs/building_maps.md."
        ),
    )
    p.add_argument(
        "folder",
        nargs="?",
        type=Path,
        help="RGB-D folder, a folder of them, or a list file (default: the bundled frames)",
    )
    p.add_argument(
        "--out",
        type=Path,
        help=f"map file (default: {DEFAULT_OUT}); for many scans, the maps' folder",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing map files")
    p.add_argument("--depth-scale", type=float, help="raw depth units per metre")
    p.add_argument("--up-axis", help="the dataset world's up axis (x, y, z, -x, -y, -z)")
    p.add_argument("--max-frames", type=int, help="stop after this many frames")
    p.add_argument("--stride", type=int, default=1, help="use every k-th frame")
    p.add_argument("--voxel-size", type=float, default=0.02, help="Gaussian voxel (m), 0.001-1")
    p.add_argument(
        "--embedder",
        choices=EMBEDDERS,
        default="minilm",
        help="text embedder (hashing: fast, dependency-free, less accurate)",
    )
    p.add_argument(
        "--perception",
        choices=PERCEPTIONS,
        default="annotated",
        help="annotated: annotations/ masks and labels; geometric: model-free segments "
        "named by --labels (glmap_tools.perception.labels_file); geometric+mllm: named by "
        "the vision model --llm-model (Ollama); mllm: the paper's MLLM + GroundingDINO "
        "(--detector) + SAM (--segmenter)",
    )
    p.add_argument("--detector", type=Path, help="GroundingDINO model folder (--perception mllm)")
    p.add_argument("--segmenter", type=Path, help="SAM model folder (--perception mllm)")
    p.add_argument(
        "--labels",
        type=Path,
        help="labels file for --perception geometric (default for the bundled frames: "
        "the bundled labels file)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    g = p.add_argument_group("many scans (FOLDER holds scan folders, or lists them)")
    g.add_argument(
        "--workers",
        type=int,
        help="scans built at once: local processes (default 1) or Ray tasks (default: the "
        "cluster's CPUs)",
    )
    g.add_argument("--ray-address", help="build on Ray: local, auto, HOST:PORT or ray://HOST:PORT")
    g.add_argument("--summary", type=Path, help=f"summary JSON (default: <out>/{SUMMARY_NAME})")
    add_llm_arguments(p, scorer=False)
    p.set_defaults(func=run_build)


def settings_from(args: argparse.Namespace) -> BuildSettings:
    """The `BuildSettings` of parsed `glmap build` arguments."""
    labels = args.labels
    if labels is None and args.folder is None and args.perception == "geometric":
        labels = bundled_folder().with_name(f"{BUNDLED}.labels.json")
    return BuildSettings(
        depth_scale=args.depth_scale,
        up_axis=args.up_axis,
        max_frames=args.max_frames,
        stride=args.stride,
        voxel_size=args.voxel_size,
        embedder=args.embedder,
        perception=args.perception,
        labels=labels,
        detector=args.detector,
        segmenter=args.segmenter,
        llm=settings_from_args(args),
    )


def is_many(source: Path | None) -> bool:
    """Whether `source` names many scans (a list file, or a folder that is not one scan)."""

    if source is None:
        return False
    return source.is_file() or (source.is_dir() and not is_sequence(source))


def run_build(args: argparse.Namespace) -> int:
    if is_many(args.folder):
        return _run_many(args)
    for flag, value in (
        ("--workers", args.workers),
        ("--ray-address", args.ray_address),
        ("--summary", args.summary),
    ):
        if value is not None:
            raise InvalidInputError(
                f"{flag} is for many scans, but {str(args.folder)!r} is one RGB-D folder; "
                "pass the folder that holds the scan folders (or a list file), or drop "
                f"{flag}."
            )
    return _run_one(args)


def _run_one(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    bar = tqdm(total=0, unit="frame", disable=args.quiet)

    def progress(done: int, total: int) -> None:
        if total:
            bar.total = total
            bar.refresh()
        bar.update(done)

    out: Path = args.out or DEFAULT_OUT
    try:
        built = build_map(
            args.folder or bundled_folder(),
            out,
            settings_from(args),
            overwrite=args.overwrite,
            progress=progress,
        )
    finally:
        bar.close()
    print(format_summary(built.glmap, built.sequence, out, built.stats))
    return 0


def _run_many(args: argparse.Namespace) -> int:

    if args.out is None:
        raise InvalidInputError(
            f"{str(args.folder)!r} holds many scans; pass --out FOLDER for their maps "
            "(<scan>.glmap each)."
        )
    result = build_many(
        args.folder,
        args.out,
        settings_from(args),
        workers=args.workers,
        ray_address=args.ray_address,
        overwrite=args.overwrite,
        summary=args.summary,
        progress=not args.quiet,
    )
    print(format_table(result.rows))
    built, skipped, failed = (result.count(s) for s in ("built", "skipped", "failed"))
    frames, cpu_s = cpu_per_frame(result.rows)
    cost = f" ({1e3 * cpu_s / frames:.0f} CPU ms per frame)" if frames else ""
    print(
        f"built {built}, skipped {skipped}, failed {failed} scan(s); {frames} frames in "
        f"{result.wall_s:.0f} s{cost}; maps in {args.out}, summary in {result.summary}"
    )
    if failed:
        print(f"rerun the same command to retry the {failed} failed scan(s)")
    return 1 if failed else 0


def format_summary(glmap: GLMap, sequence: RGBDSequence, out: Path, stats: BuildStats) -> str:
    """A human-readable summary of a built map."""
    s = glmap.summary()
    unannotated = stats.unannotated
    lines = [
        f"GLMap {out}  ({out.stat().st_size / 1024:.0f} KiB, built in {stats.seconds:.1f} s: "
        f"{stats.frames_per_s:.1f} frames/s, peak memory {stats.peak_rss_mb:.0f} MiB)",
        f"  source: {sequence.name} ({sequence.format}, {s.frames} frames, "
        f"depth scale {sequence.depth_scale:g}, up axis {sequence.up_axis})",
        f"  {s.instances} instances, {s.regions} regions, {s.gaussians} Gaussians "
        f"({s.gaussian_bytes / max(s.gaussians, 1):.0f} B each), "
        f"{s.grid_cells} grid cells, floor z = {s.floor_z or 0.0:.2f} m",
    ]
    if unannotated:
        lines.append(
            f"  {unannotated} frame(s) had no annotations: they updated occupancy only "
            "(give annotations/<stem>.png + .json for instances)"
        )
    for unit in sorted(glmap.instances.values(), key=lambda u: u.id):
        c = unit.centroid
        lines.append(
            f"  instance {unit.id:>3} {unit.label:<14} at ({c[0]:+.2f}, {c[1]:+.2f}, {c[2]:+.2f})"
            f"  {len(unit.gaussians):>5} Gaussians  seen {unit.observations}x  "
            f"{unit.text[:60]!r}"
        )
    for region in sorted(glmap.regions.values(), key=lambda r: r.id):
        lines.append(
            f"  region   {region.id:>3} instances {list(region.instance_ids)}  {region.text[:70]!r}"
        )
    return "\n".join(lines)
