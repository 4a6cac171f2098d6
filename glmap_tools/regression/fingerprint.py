"""Fingerprints of a map and of a frame's update report, and the paths where two records
differ: what the replay check (`replay.py`, `against.py`) compares."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np


def digest(*arrays: np.ndarray) -> str:
    """SHA-256 of the arrays' dtypes, shapes and bytes (16 hex digits)."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def map_fingerprint(glmap: Any) -> dict[str, Any]:
    """Every unit's fields (arrays as digests), the grid, occupancy and structure digests."""
    inst = {
        str(i): [
            u.label,
            u.text,
            u.observations,
            u.first_frame,
            u.last_frame,
            digest(u.embedding),
            len(u.gaussians),
            digest(
                u.gaussians.means,
                u.gaussians.covs,
                u.gaussians.colors,
                u.gaussians.opacities,
                u.gaussians.counts,
            ),
        ]
        for i, u in sorted(glmap.instances.items())
    }
    regions = {
        str(i): [
            r.text,
            list(r.instance_ids),
            r.observations,
            r.first_frame,
            r.last_frame,
            digest(r.embedding),
        ]
        for i, r in sorted(glmap.regions.items())
    }
    cells = [
        (uid, sorted(glmap.grid.cells_of_unit(uid)))
        for uid in sorted(set(glmap.instances) | set(glmap.regions))
    ]
    occ = sorted(glmap.occupancy.chunks.items())
    structure = glmap.structure.gaussians()
    return {
        "instances": inst,
        "regions": regions,
        "grid": hashlib.sha256(repr(cells).encode()).hexdigest()[:16],
        "occupancy": digest(np.array([k for k, _ in occ]), *(v for _, v in occ)),
        "structure": [len(structure), digest(structure.means, structure.covs, structure.colors)],
        "next_id": glmap.next_id,
        "floor_z": repr(glmap.floor_z),
        "fused_into": sorted(glmap.fused_into.items()),
    }


def report_fields(report: Any) -> list[Any]:
    """A frame's update report: what was added, merged, fused and skipped."""
    return [
        [(c.local_id, c.global_id) for c in report.instances_added],
        [(c.local_id, c.global_id, repr(c.similarity)) for c in report.instances_merged],
        [(c.local_id, c.global_id) for c in report.regions_added],
        [(c.local_id, c.global_id, repr(c.similarity)) for c in report.regions_merged],
        sorted(report.fused.items()),
        [(s.local_id, s.kind) for s in report.skipped],
        report.gaussians_added,
        report.structure_gaussians,
    ]


def differences(a: Any, b: Any, where: str = "", limit: int = 20) -> list[str]:
    """Paths where two JSON values differ (at most `limit`)."""
    out: list[str] = []
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}/{k}: only in {'after' if k in a else 'before'}")
            else:
                out += differences(a[k], b[k], f"{where}/{k}", limit - len(out))
            if len(out) >= limit:
                break
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{where}: length {len(a)} != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            out += differences(x, y, f"{where}[{i}]", limit - len(out))
            if len(out) >= limit:
                break
    elif a != b:
        out.append(f"{where}: {a!r} != {b!r}")
    return out[:limit]
