"""The scans of a many-folder build: sub-folders of a parent folder, or a list file's lines."""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from glmap_tools.errors import InvalidInputError
from glmap_tools.ingest import redwood, tum

MAP_SUFFIX = ".glmap"
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]*")


@dataclass(frozen=True)
class Scan:
    """One folder to build: its map is `<out>/<name>.glmap`."""

    name: str
    folder: Path


def is_sequence(folder: Path) -> bool:
    """Whether `folder` looks like a Redwood/Open3D, TUM or `glmap sim tour` folder."""
    return redwood.is_redwood(folder) or tum.is_tum(folder)


def _what_is_in(folder: Path) -> list[str]:
    return sorted(p.name + ("/" if p.is_dir() else "") for p in folder.iterdir())[:12]


def scans_in_folder(parent: Path) -> list[Scan]:
    """The sub-folders of `parent` that are RGB-D sequences, by name (hidden ones skipped).

    Raises:
        InvalidInputError: no sub-folder is a sequence.
    """
    scans = [
        Scan(p.name, p)
        for p in sorted(parent.iterdir())
        if p.is_dir() and not p.name.startswith(".") and is_sequence(p)
    ]
    if not scans:
        raise InvalidInputError(
            f"nothing to build: no sub-folder of {str(parent)!r} is an RGB-D sequence (it "
            f"holds {_what_is_in(parent)}). A scan folder needs {redwood.REQUIRED} (Redwood) "
            f"or {tum.REQUIRED} (TUM); pass the folder that holds the scan folders, or a "
            "text file listing them."
        )
    return scans


def scans_in_list(path: Path) -> list[Scan]:
    """The scans a list file names: one `[NAME=]FOLDER` a line ('#' comments, blanks skipped).

    Relative folders are taken from the list file's folder; NAME defaults to the folder's name.

    Raises:
        InvalidInputError: a line names a missing folder, a folder that is not a sequence,
            or a bad NAME; or the file lists nothing.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise InvalidInputError(
            f"cannot read the list file {str(path)!r} ({err}); pass a text file with one "
            "scan folder per line."
        ) from err
    scans = []
    for n, line in enumerate(text.splitlines(), 1):
        entry = line.strip()
        if not entry or entry.startswith("#"):
            continue
        name, sep, where = entry.partition("=")
        if not sep:
            name, where = "", entry
        folder = Path(where.strip()).expanduser()
        folder = folder if folder.is_absolute() else path.parent / folder
        where_said = f"{str(path)!r} line {n}"
        if not folder.is_dir():
            raise InvalidInputError(
                f"{where_said} names {str(folder)!r}, which is not a folder; fix the path "
                "(relative paths are read from the list file's folder) or remove the line."
            )
        if not is_sequence(folder):
            raise InvalidInputError(
                f"{where_said}: {str(folder)!r} is not an RGB-D sequence (it holds "
                f"{_what_is_in(folder)}); a scan folder needs {redwood.REQUIRED} (Redwood) "
                f"or {tum.REQUIRED} (TUM)."
            )
        scans.append(Scan(name.strip() or folder.resolve().name, folder))
    if not scans:
        raise InvalidInputError(
            f"nothing to build: the list file {str(path)!r} names no folder; write one "
            "scan folder per line ([NAME=]FOLDER)."
        )
    return scans


def find_scans(source: Path) -> list[Scan]:
    """The scans of a parent folder or a list file, with names checked.

    Raises:
        InvalidInputError: `source` does not exist, nothing to build, a bad list line, a
            name that cannot be a file name, or two scans with one name.
    """
    if source.is_file():
        scans = scans_in_list(source)
    elif source.is_dir():
        scans = scans_in_folder(source)
    else:
        raise InvalidInputError(
            f"{str(source)!r} does not exist; pass an RGB-D folder, a folder of them, or a "
            "text file listing them."
        )
    for scan in scans:
        if not _NAME.fullmatch(scan.name):
            raise InvalidInputError(
                f"scan name {scan.name!r} ({str(scan.folder)!r}) cannot name a map file; use "
                "letters, digits and . _ + - (give a name in a list file: NAME=FOLDER)."
            )
    by_name: dict[str, list[Path]] = {}
    for scan in scans:
        by_name.setdefault(scan.name, []).append(scan.folder)
    twice = {name: folders for name, folders in by_name.items() if len(folders) > 1}
    if twice:
        name, folders = next(iter(twice.items()))
        raise InvalidInputError(
            f"{len(twice)} scan name(s) are used twice, e.g. {name!r} for "
            f"{[str(f) for f in folders]}; their maps would overwrite each other. Name them "
            "in a list file (NAME=FOLDER, one a line)."
        )
    return scans


def map_path(out: Path, scan: Scan) -> Path:
    return out / f"{scan.name}{MAP_SUFFIX}"


def stale_files(out: Path, scans: Iterable[Scan]) -> list[Path]:
    """Temporary files an interrupted build of these scans left in `out`."""
    found: list[Path] = []
    if not out.is_dir():
        return found
    for scan in scans:
        name = map_path(out, scan).name
        found += sorted(out.glob(f".{name}.*.tmp"))  # MapStore's final write
        found += [p for p in (out / f".{name}.building",) if p.exists()]  # a per-frame build
    return found
