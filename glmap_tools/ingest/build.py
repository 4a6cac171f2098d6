"""Build one map file from one RGB-D folder: the work behind `glmap build`, per scan.

The fast pipeline (`FAST`) reads, decodes and perceives frame k+1 on a thread while frame
k fuses (`prefetch.py`), embeds each frame's descriptions on that thread too (the embedder's
cache then answers fusion), keeps BLAS to one thread (OpenBLAS threads spin against the
numba and loader threads: a [300k, 3] pose transform took 144 ms on two busy cores
against 18 ms on one), and builds the map in memory, writing the file once at the end
(temporary file beside the target, then a rename). `REFERENCE` is the plain loop: frames
read in turn, every frame committed to the store. Both give the same map
(tests/test_build_fast.py); `python -m glmap_tools.bench build` compares their speed.
"""

from __future__ import annotations

import os
import resource
import time
from collections.abc import Callable, Iterator
from contextlib import nullcontext, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.ingest.datasets import open_sequence
from glmap_tools.ingest.prefetch import prefetched
from glmap_tools.language import embed, minilm
from glmap_tools.language.backends import LLMSettings, make_text_merger
from glmap_tools.perception.backends import model_perception
from glmap_tools.perception.labelling import semantics_from_labels
from glmap_tools.perception.labels_file import FrameLabels, load_labels_file, pointed_labels
from glmap_tools.perception.semantics import FrameSemantics

if TYPE_CHECKING:
    from glmap_tools.ingest.datasets import IngestFrame, RGBDSequence
    from glmap_tools.language.embed import Embedder
    from glmap_tools.map import GLMap

# Imports inside functions stay there: gaussians, scipy, threadpoolctl load on first use: `glmap`
# imports every command module to build its parser.

PERCEPTIONS = ("annotated", "geometric", "geometric+mllm", "mllm")
EMBEDDERS = ("minilm", "hashing")

# (frames done, frames added to the total): (0, n) once the folder is open, then (1, 0)
# per fused frame.
Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class BuildSettings:
    """How to read a folder and build its map (the options of `glmap build`).

    Attributes:
        depth_scale: raw depth units per metre (None: the format's default).
        up_axis: the dataset world's up axis (None: the format's default).
        max_frames: stop after this many frames (None: all).
        stride: use every k-th frame.
        voxel_size: Gaussian voxel in metres.
        embedder: "minilm" (the bundled model) or "hashing" (fast, less accurate).
        perception: "annotated" (annotations/ masks and labels), "geometric" (model-free
            segments named by `labels`), "geometric+mllm" or "mllm" (vision model).
        labels: the labels file of "geometric".
        detector: GroundingDINO model folder ("mllm").
        segmenter: SAM model folder ("mllm").
        llm: text merger and vision-model settings.
    """

    depth_scale: float | None = None
    up_axis: str | None = None
    max_frames: int | None = None
    stride: int = 1
    voxel_size: float = 0.02
    embedder: str = "minilm"
    perception: str = "annotated"
    labels: Path | None = None
    detector: Path | None = None
    segmenter: Path | None = None
    llm: LLMSettings = field(default_factory=LLMSettings)


@dataclass(frozen=True)
class Pipeline:
    """How frames reach the map.

    Attributes:
        prefetch: read, perceive and embed the next frame on a thread.
        in_memory: build in memory and write the file once (False: commit every frame).
        blas_threads: BLAS threads while building (None: as the process has them).
    """

    prefetch: bool
    in_memory: bool
    blas_threads: int | None


FAST = Pipeline(prefetch=True, in_memory=True, blas_threads=1)
REFERENCE = Pipeline(prefetch=False, in_memory=False, blas_threads=None)


@dataclass(frozen=True)
class BuildStats:
    """What building one map took and gave.

    Attributes:
        frames: frames fused.
        unannotated: frames without annotations (occupancy only), in "annotated" mode.
        instances: instances in the map.
        regions: regions in the map.
        gaussians: instance Gaussians in the map.
        seconds: wall time from opening the folder to the renamed file.
        cpu_s: CPU seconds of this process (all threads) over the same span.
        peak_rss_mb: the process's peak resident memory (MiB) when the map was written.
    """

    frames: int
    unannotated: int
    instances: int
    regions: int
    gaussians: int
    seconds: float
    cpu_s: float
    peak_rss_mb: float

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0


@dataclass
class BuiltMap:
    """A finished build: the map (its store closed), the sequence read and the figures."""

    glmap: GLMap
    sequence: RGBDSequence
    stats: BuildStats


def peak_rss_mb() -> float:
    """This process's peak resident set size so far, in MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def cpu_seconds() -> float:
    """CPU seconds (user + system, all threads) this process has used so far."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def make_embedder(name: str) -> Embedder:
    """The text embedder named by `--embedder`."""

    return embed.HashingEmbedder() if name == "hashing" else minilm.default_embedder()


def check_settings(settings: BuildSettings) -> None:
    """Refuse settings that cannot work, before anything is read or written.

    Raises:
        InvalidInputError: an unknown perception or embedder, "geometric" without a labels
            file, or "mllm" without its model folders.
    """
    if settings.perception not in PERCEPTIONS:
        raise InvalidInputError(
            f"perception {settings.perception!r} is not one of {list(PERCEPTIONS)}."
        )
    if settings.embedder not in EMBEDDERS:
        raise InvalidInputError(f"embedder {settings.embedder!r} is not one of {list(EMBEDDERS)}.")
    if settings.perception == "geometric" and settings.labels is None:
        raise InvalidInputError(
            "--perception geometric needs --labels FILE: the names of each frame's objects, "
            "by pixels pointing at them (see glmap_tools.perception.labels_file)."
        )
    if settings.perception == "mllm" and (settings.detector is None or settings.segmenter is None):
        raise InvalidInputError(
            "--perception mllm needs --detector FOLDER (GroundingDINO) and --segmenter "
            "FOLDER (SAM): local model folders; nothing is downloaded at run time."
        )


def make_perception(settings: BuildSettings) -> Callable[[IngestFrame], FrameSemantics] | None:
    """Frame -> semantics for the model-free or model perceptions; None for "annotated"."""
    check_settings(settings)
    if settings.perception == "annotated":
        return None
    if settings.perception in ("geometric+mllm", "mllm"):
        backend = model_perception(
            settings.perception, settings.llm, settings.detector, settings.segmenter
        )
        return lambda item: backend(item.frame)
    from glmap_tools.perception.geometric import segment_frame

    assert settings.labels is not None  # check_settings
    frames = load_labels_file(settings.labels)

    def perceive(item: IngestFrame) -> FrameSemantics:
        segments = segment_frame(item.frame)
        named = frames.get(item.rgb_path.stem, FrameLabels((), ()))
        labels, groups, _ = pointed_labels(segments, named)
        return semantics_from_labels(segments, labels, groups)

    return perceive


def _semantics(
    item: IngestFrame, perceive: Callable[[IngestFrame], FrameSemantics] | None
) -> FrameSemantics | None:
    """The frame's semantics, or None for an unannotated frame in "annotated" mode."""
    return perceive(item) if perceive is not None else item.semantics


def _warm_embeddings(embedder: Any, semantics: FrameSemantics | None) -> None:
    """Embed the texts fusion will ask for, so that the embedder's cache answers it then.

    Only for a caching embedder (MiniLM; hashing is cheaper than a cache). A cached vector
    is the one fusion would compute (vectors never depend on what is batched with them).
    """
    if semantics is None or not getattr(embedder, "cache_size", 0):
        return
    texts = [o.text for o in semantics.objects] + [g.description.strip() for g in semantics.groups]
    texts = [t for t in texts if t]
    if texts:
        with suppress(Exception):  # a warm-up only: fusion's own call reports any error
            embedder.embed(texts)


def _blas_limit(threads: int | None) -> Any:
    if threads is None:
        return nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=threads, user_api="blas")


def build_map(
    folder: Path,
    out: Path,
    settings: BuildSettings,
    *,
    overwrite: bool = False,
    progress: Progress | None = None,
    pipeline: Pipeline = FAST,
) -> BuiltMap:
    """Build the map of `folder` into the file `out`; a failed build leaves no file.

    Args:
        folder: a Redwood/Open3D, TUM or `glmap sim tour` folder.
        out: the map file to write (its folder is created).
        settings: how to read and build.
        overwrite: replace an existing `out`.
        progress: told (0, n) when the folder's n frames are known, then (1, 0) per frame.
        pipeline: FAST or REFERENCE (the same map; see the module docstring).

    Raises:
        StoreError: `out` exists (without `overwrite`) or cannot be written.
        InvalidInputError: bad settings, an unreadable folder or frame, a bad annotation.
    """
    from glmap_tools.map import GLMap, MapConfig

    if out.exists() and not overwrite:
        raise StoreError(f"{str(out)!r} exists; pass --overwrite to replace it or choose --out.")
    if out.is_dir():
        raise StoreError(f"{str(out)!r} is a folder; pass the path of a map file as --out.")
    check_settings(settings)
    start, cpu_start = time.perf_counter(), cpu_seconds()
    sequence = open_sequence(
        folder,
        depth_scale=settings.depth_scale,
        up_axis=settings.up_axis,
        max_frames=settings.max_frames,
        stride=settings.stride,
    )
    perceive = make_perception(settings)
    embedder = make_embedder(settings.embedder)
    merger = make_text_merger(settings.llm, embedder)
    config = MapConfig(voxel_size=settings.voxel_size)
    progress = progress or (lambda done, total: None)
    progress(0, len(sequence))

    frames = _frames(sequence, perceive, embedder, pipeline)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.building")
    if pipeline.in_memory:
        glmap = GLMap(config, embedder=embedder, text_merger=merger)
    else:
        tmp.unlink(missing_ok=True)
        glmap = GLMap.open(tmp, config, embedder=embedder, text_merger=merger)
    unannotated = _integrate(glmap, frames, out, tmp, pipeline, progress)
    s = glmap.summary()
    stats = BuildStats(
        frames=s.frames,
        unannotated=unannotated,
        instances=s.instances,
        regions=s.regions,
        gaussians=s.gaussians,
        seconds=time.perf_counter() - start,
        cpu_s=cpu_seconds() - cpu_start,
        peak_rss_mb=peak_rss_mb(),
    )
    return BuiltMap(glmap, sequence, stats)


def _frames(
    sequence: RGBDSequence,
    perceive: Callable[[IngestFrame], FrameSemantics] | None,
    embedder: Embedder,
    pipeline: Pipeline,
) -> Iterator[tuple[IngestFrame, FrameSemantics | None]]:
    """The sequence's frames with their semantics (None: unannotated), each prepared on a
    thread ahead of use when the pipeline prefetches."""

    def prepare(k: int) -> tuple[IngestFrame, FrameSemantics | None]:
        item = sequence.load(k)
        semantics = _semantics(item, perceive)
        if pipeline.prefetch:
            _warm_embeddings(embedder, semantics)
        return item, semantics

    return (
        prefetched(prepare, len(sequence))
        if pipeline.prefetch
        else (prepare(k) for k in range(len(sequence)))
    )


def _integrate(
    glmap: GLMap,
    frames: Iterator[tuple[IngestFrame, FrameSemantics | None]],
    out: Path,
    tmp: Path,
    pipeline: Pipeline,
    progress: Progress,
) -> int:
    """Fuse every frame into `glmap` and write it to `out` (through `tmp` or a temporary
    file and a rename; nothing is left behind on failure); the unannotated frames' count."""
    unannotated = 0
    try:
        with _blas_limit(pipeline.blas_threads):
            for item, semantics in frames:
                if semantics is None:
                    unannotated += 1
                    semantics = FrameSemantics()
                glmap.integrate(item.frame, semantics, item.index)
                progress(1, 0)
        if pipeline.in_memory:
            from glmap_tools.map.store import MapStore

            MapStore.create_from(out, glmap, overwrite=True).close()  # temp file + rename
        else:
            glmap.close()
            os.replace(tmp, out)
    except BaseException:
        if not pipeline.in_memory:
            glmap.close()
            tmp.unlink(missing_ok=True)
        raise
    finally:
        if hasattr(frames, "close"):
            frames.close()
    return unannotated
