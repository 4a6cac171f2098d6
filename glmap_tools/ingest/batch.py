"""`glmap build` over many folders: one map per scan, resumable, on local workers or Ray.

The scans are the sub-folders of a parent folder that look like RGB-D sequences, or the
folders a list file names (`scans.py`). Each becomes `<out>/<scan>.glmap`, built by one
task (`engines.py`); a map that exists is skipped (`overwrite` rebuilds it), a map is only
ever written whole (temporary file beside it, then a rename; temporary files an
interrupted run left are removed), and a scan that fails is reported in the summary while
the others go on. Everything is checked before anything on disk changes.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from glmap_tools.atomic import write_atomic
from glmap_tools.errors import InvalidInputError, StoreError
from glmap_tools.ingest.build import BuildSettings, check_settings
from glmap_tools.ingest.engines import ScanTask, run_local, run_ray
from glmap_tools.ingest.scans import Scan, find_scans, map_path, stale_files
from glmap_tools.ingest.summary import (
    SUMMARY_NAME,
    ScanResult,
    in_order,
    read_summary,
    skipped_row,
    summary_json,
)
from glmap_tools.ray_cluster import import_ray, resolve_address

# Imports inside functions stay there: tqdm load on first use: `glmap` imports every command module
# to build its parser.


@dataclass
class ManyResult:
    """What a many-folder build did.

    Attributes:
        rows: one per scan, in the scans' order.
        summary: the summary JSON written.
        wall_s: seconds the builds took (0 when nothing was built).
        removed: temporary files of an interrupted run that were removed.
    """

    rows: list[ScanResult]
    summary: Path
    wall_s: float
    removed: list[Path]

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.rows)


def check_out_folder(out: Path) -> None:
    """Refuse an --out that is a file.

    Raises:
        StoreError: `out` exists and is not a folder.
    """
    if out.exists() and not out.is_dir():
        raise StoreError(
            f"--out {str(out)!r} is a file; building many scans writes <scan>.glmap files into "
            "a folder: pass a folder path (it is created)."
        )


def check_many_settings(settings: BuildSettings) -> None:
    """Refuse settings a many-folder build cannot use.

    Raises:
        InvalidInputError: "geometric" perception (one labels file names one folder's
            frames), or settings `check_settings` refuses.
    """
    if settings.perception == "geometric":
        raise InvalidInputError(
            "--perception geometric names one folder's segments from one --labels file; "
            "build such folders one at a time (glmap build FOLDER --labels FILE), or use "
            "annotated, geometric+mllm or mllm perception."
        )
    check_settings(settings)


def _check_workers(workers: int | None) -> None:
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise InvalidInputError(f"--workers {workers!r} must be an integer >= 1.")


class _Bars:
    """A bar over scans and one over frames (of the scans started so far)."""

    def __init__(self, scans: int, enabled: bool) -> None:
        from tqdm import tqdm

        self.scans = tqdm(total=scans, unit="scan", position=0, disable=not enabled)
        self.frames = tqdm(total=0, unit="frame", position=1, disable=not enabled)

    def update_frames(self, done: int, total: int) -> None:
        if (done, total) != (self.frames.n, self.frames.total):
            self.frames.total = total
            self.frames.n = done
            self.frames.refresh()

    def scan_done(self, failed: int) -> None:
        self.scans.update(1)
        if failed:
            self.scans.set_postfix(failed=failed)

    def close(self) -> None:
        self.frames.close()
        self.scans.close()


def build_many(
    source: Path,
    out: Path,
    settings: BuildSettings,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    overwrite: bool = False,
    summary: Path | None = None,
    progress: bool = True,
    echo: Callable[[str], None] = print,
) -> ManyResult:
    """Build a map per scan of `source` (a folder of scan folders, or a list file) into `out`.

    Args:
        source: the parent folder or the list file (see `scans.find_scans`).
        out: the folder of the maps (created).
        settings: how to build each scan.
        workers: scans built at once: local processes (default 1), or Ray tasks (default:
            the cluster's CPUs).
        ray_address: build on Ray ('local', 'auto', HOST:PORT or ray://HOST:PORT).
        overwrite: rebuild scans whose maps exist.
        summary: the summary JSON (default `<out>/build-summary.json`).
        progress: show the bars.
        echo: where notes go (skipped scans, removed temporary files).

    Raises:
        InvalidInputError: nothing to build, a missing folder, a bad list line, duplicate
            scan names, bad settings or workers, a malformed Ray address.
        StoreError: `out` is a file, or `summary` a folder.
        RayUnavailableError: Ray missing or the address not answering.
    """
    scans = find_scans(source)
    check_out_folder(out)
    summary_path = summary or out / SUMMARY_NAME
    if summary_path.is_dir():
        raise StoreError(f"--summary {str(summary_path)!r} is a folder; pass a file path.")
    check_many_settings(settings)
    _check_workers(workers)
    todo = [s for s in scans if overwrite or not map_path(out, s).exists()]
    if ray_address is not None:
        resolve_address(ray_address)  # a malformed address fails here, before any write
        if todo:
            import_ray()
    rows = _skipped_rows(scans, todo, out, summary_path, echo)
    removed = _remove_stale_files(out, todo, echo)
    tasks = _scan_tasks(todo, out, settings, overwrite, workers, ray_address)
    start = time.perf_counter()
    bars = _Bars(len(tasks), progress and bool(tasks))
    engine: Iterator[ScanResult]
    try:
        if not tasks:
            engine = iter(())
        elif ray_address is not None:
            engine = run_ray(tasks, workers, ray_address, bars.update_frames)
        else:
            engine = run_local(tasks, workers or 1, bars.update_frames)
        for row in engine:
            rows.append(row)
            bars.scan_done(sum(r.status == "failed" for r in rows))
    finally:
        bars.close()
        wall_s = time.perf_counter() - start if tasks else 0.0
        rows = in_order(rows, scans)
        summary_path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(summary_path, [summary_json(rows, wall_s, settings).encode()])
    return ManyResult(rows, summary_path, wall_s, removed)


def _skipped_rows(
    scans: list[Scan], todo: list[Scan], out: Path, summary_path: Path, echo: Callable[[str], None]
) -> list[ScanResult]:
    """The summary rows of the scans not to build (their maps exist), as the earlier
    summary has them."""
    earlier = read_summary(summary_path)
    rows = [skipped_row(s, out, earlier) for s in scans if s not in todo]
    if rows:
        echo(
            f"skipping {len(rows)} scan(s) whose maps exist in {out} (pass --overwrite to "
            "rebuild them)"
        )
    return rows


def _remove_stale_files(out: Path, todo: list[Scan], echo: Callable[[str], None]) -> list[Path]:
    """Create `out` and remove the temporary files an interrupted build of `todo` left there;
    the removed files."""
    out.mkdir(parents=True, exist_ok=True)
    removed = stale_files(out, todo)
    for path in removed:
        path.unlink(missing_ok=True)
    if removed:
        echo(f"removed {len(removed)} temporary file(s) an interrupted build left in {out}")
    return removed


def _scan_tasks(
    todo: list[Scan],
    out: Path,
    settings: BuildSettings,
    overwrite: bool,
    workers: int | None,
    ray_address: str | None,
) -> list[ScanTask]:
    """One build task per scan, with numba's threads shared among the local workers (one
    each on Ray)."""
    local_workers = workers or 1
    return [
        ScanTask(
            s.name,
            str(s.folder.resolve()),
            str(map_path(out, s).resolve()),
            settings,
            overwrite=overwrite,
            numba_threads=1 if ray_address else max(1, (os.cpu_count() or 1) // local_workers),
        )
        for s in todo
    ]
