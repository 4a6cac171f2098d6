"""The summary of a many-folder build: one row per scan, as a text table and as JSON."""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from glmap_tools.ingest.build import BuildSettings
from glmap_tools.ingest.scans import Scan, map_path

SUMMARY_NAME = "build-summary.json"


@dataclass(frozen=True)
class ScanResult:
    """One row of the build summary.

    Attributes:
        scan: the scan's name.
        folder: its folder.
        map: the map file.
        status: "built", "skipped" (the map existed) or "failed".
        frames: frames fused (None when unknown: failed, or skipped with no earlier row).
        instances: instances in the map.
        regions: regions in the map.
        gaussians: instance Gaussians in the map.
        seconds: build wall time.
        frames_per_s: frames / seconds.
        cpu_s: CPU seconds of the scan's process, start-up (imports, embedder) included.
        peak_rss_mb: the building process's peak resident memory, MiB.
        host: the machine that built it.
        error: why it failed ("" otherwise).
    """

    scan: str
    folder: str
    map: str
    status: str
    frames: int | None = None
    instances: int | None = None
    regions: int | None = None
    gaussians: int | None = None
    seconds: float | None = None
    frames_per_s: float | None = None
    cpu_s: float | None = None
    peak_rss_mb: float | None = None
    host: str = ""
    error: str = ""


_TEXT_FIELDS = ("scan", "folder", "map", "status", "host", "error")
_COUNT_FIELDS = ("frames", "instances", "regions", "gaussians")
_FIGURE_FIELDS = ("seconds", "frames_per_s", "cpu_s", "peak_rss_mb")


def _row_ok(row: Any) -> bool:
    """Whether an earlier summary's row holds each field as a ScanResult does."""
    if not isinstance(row, dict) or not isinstance(row.get("scan"), str):
        return False
    for name, value in row.items():
        if name in _TEXT_FIELDS and not isinstance(value, str):
            return False
        if name in _COUNT_FIELDS + _FIGURE_FIELDS and value is not None:
            whole = isinstance(value, int) and not isinstance(value, bool)
            if not (whole or (name in _FIGURE_FIELDS and isinstance(value, float))):
                return False
    return True


def read_summary(path: Path) -> dict[str, ScanResult]:
    """The rows of an earlier summary JSON by scan name ({} when absent or unreadable; a row
    whose fields are not a summary row's is left out)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    scans = data.get("scans") if isinstance(data, dict) else None
    if not isinstance(scans, list):
        return {}
    fields = set(ScanResult.__dataclass_fields__)
    rows = []
    for r in scans:
        if _row_ok(r):
            try:
                rows.append(ScanResult(**{k: v for k, v in r.items() if k in fields}))
            except TypeError:  # a field without a default is missing
                continue
    return {r.scan: r for r in rows}


def skipped_row(scan: Scan, out: Path, earlier: dict[str, ScanResult]) -> ScanResult:
    """The row of a scan whose map exists: its earlier figures when a summary has them."""
    before = earlier.get(scan.name)
    row = ScanResult(scan.name, str(scan.folder), str(map_path(out, scan)), "skipped")
    if before is not None and before.status == "built":
        row = replace(before, folder=row.folder, map=row.map, status="skipped")
    return row


def cpu_per_frame(rows: Iterable[ScanResult]) -> tuple[int, float]:
    """(frames, CPU seconds) of the rows built in this run."""
    built = [r for r in rows if r.status == "built" and r.frames and r.cpu_s is not None]
    return sum(r.frames or 0 for r in built), sum(r.cpu_s or 0.0 for r in built)


def summary_json(rows: list[ScanResult], wall_s: float, settings: BuildSettings) -> str:
    counts = {s: sum(r.status == s for r in rows) for s in ("built", "skipped", "failed")}
    frames, cpu_s = cpu_per_frame(rows)
    doc: dict[str, Any] = {
        "scans": [asdict(r) for r in rows],
        "counts": counts,
        "wall_s": round(wall_s, 2),
        "frames_built": frames,
        "cpu_s_per_frame": round(cpu_s / frames, 4) if frames else None,
        "settings": json.loads(json.dumps(asdict(settings), default=str)),
    }
    return json.dumps(doc, indent=2) + "\n"


def _cell(value: Any, digits: int = 0) -> str:
    if value is None:
        return "-"
    return f"{value:.{digits}f}" if isinstance(value, float) else str(value)


def format_table(rows: list[ScanResult]) -> str:
    """The summary as an aligned text table, one scan a row, then each failure's error."""
    head = ("scan", "frames", "instances", "regions", "seconds", "frames/s", "peak MB", "status")
    body = []
    for r in rows:
        status = "FAILED" if r.status == "failed" else r.status
        body.append(
            (
                r.scan,
                _cell(r.frames),
                _cell(r.instances),
                _cell(r.regions),
                _cell(r.seconds, 1),
                _cell(r.frames_per_s, 1),
                _cell(r.peak_rss_mb),
                status,
            )
        )
    widths = [max(len(row[k]) for row in [head, *body]) for k in range(len(head) - 1)]

    def line(row: tuple[str, ...]) -> str:
        cells = [row[0].ljust(widths[0])] + [
            c.rjust(w) for c, w in zip(row[1:-1], widths[1:], strict=True)
        ]
        return "  ".join([*cells, row[-1]])

    lines = [line(row) for row in [head, *body]]
    for r in rows:
        if r.status == "failed":
            last = (r.error.strip().splitlines() or ["?"])[-1]
            lines.append(f"FAILED {r.scan}: {last}")
    return "\n".join(lines)


def in_order(rows: Iterable[ScanResult], scans: list[Scan]) -> list[ScanResult]:
    """The rows sorted in the order of `scans`."""
    order = {s.name: k for k, s in enumerate(scans)}
    return sorted(rows, key=lambda r: order.get(r.scan, len(order)))
