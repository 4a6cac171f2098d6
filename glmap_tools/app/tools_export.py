"""export_ply: write the map, an instance or a region as a 3DGS PLY file in the maps folder.

The file is `<maps folder>/<name>.ply`: a bare name, as for saved maps, so nothing outside
the maps folder is written; it is written to a temporary file and renamed. No `from
__future__ import annotations` here: the MCP face reads these signatures at runtime.
"""

from pathlib import Path
from typing import Annotated

from pydantic import Field

from glmap_tools.app.arguments import SessionArg
from glmap_tools.app.results import Exported
from glmap_tools.app.runtime import REPLACES, Call, ToolSpec, in_thread, session_of
from glmap_tools.app.session import check_map_name, locked
from glmap_tools.app.views import EMPTY_MAP
from glmap_tools.errors import InvalidInputError, StoreError

# Imports inside functions stay there: gaussians, numba load on first use: the tools load before
# these do, in the server and the in-process toolset alike.

PLY_SUFFIX = ".ply"
ExportName = Annotated[
    str, Field(min_length=1, max_length=70, description="letters, digits, '-' or '_'")
]


def export_path(maps_dir: Path, name: str) -> Path:
    """`<maps_dir>/<name>.ply`, refusing any name that would leave the maps folder.

    Raises:
        InvalidInputError: a name with a path, a bad character, or that resolves elsewhere.
    """
    stem = check_map_name(name, PLY_SUFFIX, "export name")
    folder = maps_dir.resolve()
    path = (folder / f"{stem}{PLY_SUFFIX}").resolve()
    if path.parent != folder:
        raise InvalidInputError(
            f"export name {name!r} resolves outside the maps folder; give a bare name."
        )
    return path


def _reason(exc: StoreError) -> str:
    """Why a write failed, without the paths an OSError message carries."""
    cause = exc.__cause__
    if isinstance(cause, OSError) and cause.strerror:
        return cause.strerror
    return "write failed"


async def export_ply(
    name: ExportName,
    call: Call,
    unit_id: Annotated[int | None, Field(ge=1, le=2**62, description="omit: whole map")] = None,
    overwrite: bool = False,
    session: SessionArg = "",
) -> Exported:
    """Write the map's (or a unit's) 3D Gaussians as a 3DGS '<name>.ply'."""
    state = call.state
    target = session_of(call, session)
    path = export_path(state.config.maps_dir, name)

    def run() -> Exported:
        with locked(target) as glmap:
            if not glmap.instances:
                raise InvalidInputError(EMPTY_MAP)
            if unit_id is not None:
                glmap.unit(unit_id)  # an unknown id raises, naming the closest
            if path.is_dir():
                raise StoreError(
                    f"{path.name!r} in the maps folder is a folder; choose another name."
                )
            if path.exists() and not overwrite:
                raise StoreError(
                    f"an export named {path.name!r} already exists; pass overwrite=true "
                    "to replace it, or choose another name."
                )
            path.parent.mkdir(parents=True, exist_ok=True)
            from glmap_tools.views import export_ply as write_export

            try:
                result = write_export(glmap, path, unit_id)
            except StoreError as exc:  # its message names the absolute path: show the name
                raise StoreError(
                    f"could not write {path.name!r} in the maps folder ({_reason(exc)}); "
                    "check that the folder is writable and has space."
                ) from exc
            return Exported(
                session=target.handle,
                map_name=target.live.name,
                file=path.name,
                what=result.what,
                gaussians=result.gaussians,
                instance_ids=list(result.instance_ids),
                bytes=path.stat().st_size,
            )

    return await in_thread(run)


TOOLS = [
    ToolSpec(export_ply, REPLACES),
]
