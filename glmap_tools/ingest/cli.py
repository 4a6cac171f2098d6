"""`glmap build`: build a GLMap file from a Redwood- or TUM-style RGB-D folder."""

from __future__ import annotations

import argparse
import os
import time
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from glmap_tools.errors import StoreError
from glmap_tools.language.backends import (
    add_llm_arguments,
    make_text_merger,
    settings_from_args,
)

if TYPE_CHECKING:
    from collections.abc import Callable

    from glmap_tools.ingest.datasets import IngestFrame, RGBDSequence
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map import GLMap
    from glmap_tools.perception.semantics import FrameSemantics

BUNDLED = "redwood_livingroom1_5frames"


def bundled_folder() -> Path:
    """The five real Redwood living-room frames shipped with the package."""
    return Path(str(resources.files("glmap_tools") / "data" / BUNDLED))


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "build",
        help="build a map file from an RGB-D folder",
        description=(
            "Build a GLMap from a Redwood-style (color/, depth/, trajectory.log, intrinsics "
            "JSON) or TUM-style (rgb.txt, depth.txt, groundtruth.txt) folder. Frames with "
            "annotations/<stem>.png + .json give instances and regions; others update "
            "occupancy only. Without FOLDER, builds the bundled Redwood frames."
        ),
    )
    p.add_argument("folder", nargs="?", type=Path, help="RGB-D folder (default: bundled)")
    p.add_argument("--out", type=Path, default=Path("out/redwood.glmap"), help="map file")
    p.add_argument("--overwrite", action="store_true", help="replace an existing map file")
    p.add_argument("--depth-scale", type=float, help="raw depth units per metre")
    p.add_argument("--up-axis", help="the dataset world's up axis (x, y, z, -x, -y, -z)")
    p.add_argument("--max-frames", type=int, help="stop after this many frames")
    p.add_argument("--stride", type=int, default=1, help="use every k-th frame")
    p.add_argument("--voxel-size", type=float, default=0.02, help="Gaussian voxel (m)")
    p.add_argument(
        "--embedder",
        choices=["minilm", "hashing"],
        default="minilm",
        help="text embedder (hashing: fast, dependency-free, less accurate)",
    )
    p.add_argument(
        "--perception",
        choices=["annotated", "geometric", "geometric+mllm", "mllm"],
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
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_llm_arguments(p, scorer=False)
    p.set_defaults(func=run_build)


def _embedder(name: str) -> Embedder:
    from glmap_tools.language import embed

    return embed.HashingEmbedder() if name == "hashing" else embed.default_embedder()


def _geometric_perception(args: argparse.Namespace) -> Callable[[IngestFrame], FrameSemantics]:
    """Frame -> semantics for --perception geometric, geometric+mllm or mllm."""
    from glmap_tools.errors import InvalidInputError
    from glmap_tools.perception.geometric import segment_frame
    from glmap_tools.perception.labelling import semantics_from_labels
    from glmap_tools.perception.labels_file import FrameLabels, load_labels_file, pointed_labels

    if args.perception in ("geometric+mllm", "mllm"):
        from glmap_tools.perception.backends import model_perception

        backend = model_perception(
            args.perception, settings_from_args(args), args.detector, args.segmenter
        )
        return lambda item: backend(item.frame)
    path = args.labels
    if path is None and args.folder is None:
        path = bundled_folder().with_name(f"{BUNDLED}.labels.json")
    if path is None:
        raise InvalidInputError(
            "--perception geometric needs --labels FILE: the names of each frame's objects, "
            "by pixels pointing at them (see glmap_tools.perception.labels_file)."
        )
    frames = load_labels_file(path)

    def perceive(item: IngestFrame) -> FrameSemantics:
        segments = segment_frame(item.frame)
        named = frames.get(item.rgb_path.stem, FrameLabels((), ()))
        labels, groups, _ = pointed_labels(segments, named)
        return semantics_from_labels(segments, labels, groups)

    return perceive


def run_build(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from glmap_tools.ingest.datasets import open_sequence
    from glmap_tools.map import GLMap, MapConfig

    folder = args.folder or bundled_folder()
    out: Path = args.out
    if out.exists() and not args.overwrite:
        raise StoreError(f"{str(out)!r} exists; pass --overwrite to replace it or choose --out.")
    sequence = open_sequence(
        folder,
        depth_scale=args.depth_scale,
        up_axis=args.up_axis,
        max_frames=args.max_frames,
        stride=args.stride,
    )
    perceive = _geometric_perception(args) if args.perception != "annotated" else None
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.building")
    tmp.unlink(missing_ok=True)
    start = time.perf_counter()
    embedder = _embedder(args.embedder)
    merger = make_text_merger(settings_from_args(args), embedder)
    glmap = GLMap.open(
        tmp, MapConfig(voxel_size=args.voxel_size), embedder=embedder, text_merger=merger
    )
    unannotated = 0
    try:
        for item in tqdm(sequence.frames(), total=len(sequence), unit="frame", disable=args.quiet):
            if perceive is not None:
                glmap.integrate(item.frame, perceive(item), item.index)
            elif item.semantics is None:
                from glmap_tools.perception import FrameSemantics

                unannotated += 1
                glmap.integrate(item.frame, FrameSemantics(), item.index)
            else:
                glmap.integrate(item.frame, item.semantics, item.index)
        glmap.close()
        os.replace(tmp, out)
    except BaseException:
        glmap.close()
        tmp.unlink(missing_ok=True)
        raise
    elapsed = time.perf_counter() - start
    print(format_summary(glmap, sequence, out, elapsed, unannotated))
    return 0


def format_summary(
    glmap: GLMap, sequence: RGBDSequence, out: Path, elapsed: float, unannotated: int
) -> str:
    """A human-readable summary of a built map."""
    s = glmap.summary()
    lines = [
        f"GLMap {out}  ({out.stat().st_size / 1024:.0f} KiB, built in {elapsed:.1f} s)",
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
