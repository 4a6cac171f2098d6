"""Pydantic results of the MCP tools (their structured content), and the compact forms of
results, descriptions and schemas that a model reads."""

from __future__ import annotations

import inspect
import io
import json
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Generic, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field

from glmap_tools.map.report import MapSummary, UnitInfo, UpdateReport

if TYPE_CHECKING:
    from PIL.Image import Image as PILImage

# Imports inside functions stay there: optional: PIL.

_BARE = re.compile(r"[A-Za-z0-9_./:+-]+")


class SessionInfo(BaseModel):
    """Which session and map a call worked on."""

    session: str = Field(
        description="session handle; pass it as `session` to later calls when several "
        "clients share a stateless server (not needed over stdio)"
    )
    map_name: str | None = Field(
        description="saved map this session works on (every frame is committed to it), or "
        "null for an unsaved scratch map"
    )


class ObserveResult(SessionInfo):
    """What one observed frame changed in the map."""

    summary: str = Field(description="one line: units added and merged, map size")
    report: UpdateReport = Field(description="instances and regions added or merged, with ids")


class Hits(BaseModel):
    """Ranked matches of a text query, best first."""

    query: str
    hits: list[UnitInfo] = Field(
        description="id, description, score (similarity, higher is closer), match (false: "
        "nothing in the map fits the query well), centroid, bounds; regions list their "
        "member instance_ids"
    )
    note: str = Field(default="", description="why there are no hits, when the map is empty")


class UnitsAt(BaseModel):
    """The units around a point of the floor plan, nearest first."""

    x: float
    y: float
    radius: float
    occupancy: str = Field(description="'free', 'obstacle' or 'unknown' at (x, y)")
    units: list[UnitInfo] = Field(description="`distance` is metres from (x, y) to the unit")


class FromAgent(BaseModel):
    """Where a unit lies from the simulator agent."""

    id: int
    distance_m: float = Field(description="straight-line metres from the agent to the centroid")
    bearing_deg: float = Field(description="degrees from the agent's heading, + = to its left")


class MapInfo(SessionInfo):
    """Counts and extent of the session's map."""

    summary: MapSummary
    resources: list[str] = Field(description="glmap:// resources to read this map")
    simulator: str | None = Field(
        default=None, description="what became of the session's simulator episode, if any"
    )


class SavedMap(SessionInfo):
    """The result of save_map."""

    written: bool = Field(description="false when the map already commits every frame to this name")
    bytes: int = Field(description="size of the map file")


class MapEntry(BaseModel):
    """One saved map in the maps folder."""

    name: str
    bytes: int
    modified: str = Field(description="ISO 8601 time of the last write (UTC)")
    open: bool = Field(description="open in some session right now")


class MapList(BaseModel):
    """The saved maps (names only; no paths are accepted or shown)."""

    maps: list[MapEntry]


class Exported(SessionInfo):
    """The result of export_ply."""

    file: str = Field(description="the file written, in the server's maps folder")
    what: str = Field(description="'whole map', 'instance 3 (chair)' or 'region 9'")
    gaussians: int = Field(description="number of 3D Gaussians in the file")
    instance_ids: list[int] = Field(description="the instances whose Gaussians it holds")
    bytes: int = Field(description="size of the file")


class Picture(BaseModel):
    """An image a tool returns: the PNG or JPEG file's bytes."""

    format: Literal["png", "jpeg"]
    data: bytes

    @property
    def mime_type(self) -> str:
        return f"image/{self.format}"

    def to_pil(self) -> PILImage:
        """The image as a PIL image (RGB)."""
        from PIL import Image

        return Image.open(io.BytesIO(self.data)).convert("RGB")


class Reply(BaseModel):
    """A tool result whose text block is its JSON (the simulator, navigation and situated-QA
    tools): an optional field not given is left out of the text, not sent as null."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)

    def given(self) -> dict[str, Any]:
        """The fields given, nested ones alike, as the JSON text carries them."""
        return self.model_dump(exclude_unset=True)


D = TypeVar("D", bound=BaseModel)


class ImageResult(BaseModel, Generic[D]):
    """A result shown as text blocks and images: `data` as compact JSON, then `notes`,
    then `images` (render_view, map_summary, the simulator and navigation tools)."""

    data: D | None = None
    notes: list[str] = Field(default_factory=list)
    images: list[Picture] = Field(default_factory=list)

    def texts(self) -> list[str]:
        """The text blocks, in order."""
        head = [compact_json(data_json(self.data))] if self.data is not None else []
        return head + self.notes


def data_json(data: BaseModel) -> dict[str, Any]:
    """An ImageResult's data as its JSON text block holds it: a `Reply`'s given fields, any
    other model's every field."""
    return data.given() if isinstance(data, Reply) else data.model_dump(mode="json")

    def __str__(self) -> str:
        return as_text(self)


def pictures_of(result: object) -> list[Picture]:
    """The images that go with a tool result (none for most)."""
    if isinstance(result, ImageResult):
        return list(result.images)
    sheet = getattr(result, "sheet", None)
    return [sheet] if isinstance(sheet, Picture) else []


def as_text(result: object) -> str:
    """The text a model reads for a tool result, the same through MCP and in process."""
    if isinstance(result, ImageResult):
        return "\n".join(result.texts())
    if isinstance(result, BaseModel):
        return compact_text(result.model_dump(mode="json", by_alias=True))
    return str(result)


# ---------------------------------------------------------------------- what a model reads


def compact_json(data: Mapping[str, Any]) -> str:
    """JSON without whitespace (a model pays for every byte)."""
    return json.dumps(data, separators=(",", ":"), ensure_ascii=False)


DECIMALS = 3  # millimetres; scores to 0.001


def _scalar(value: object) -> str:
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, float):
        text = f"{value:.{DECIMALS}f}".rstrip("0").rstrip(".")
        return "0" if text in ("-0", "") else text
    if isinstance(value, int):
        return str(value)
    text = str(value)
    return text if _BARE.fullmatch(text) else json.dumps(text, ensure_ascii=False)


def _empty(value: object) -> bool:
    return value is None or value == "" or value == [] or value == {}


def _inline(value: object) -> str:
    """One value on one line: dicts as {k=v ...}, lists as [a,b], floats rounded."""
    if isinstance(value, dict):
        return "{" + " ".join(f"{k}={_inline(v)}" for k, v in value.items() if not _empty(v)) + "}"
    if isinstance(value, list):
        return "[" + ",".join(_inline(v) for v in value) + "]"
    return _scalar(value)


def compact_text(data: dict[str, Any]) -> str:
    """The text block of a structured result: one `key: value` line per field.

    A list of objects (hits, units, maps) gets one `- k=v ...` line per object. Floats are
    rounded to 3 decimals and empty or null fields left out; the structured content beside
    it keeps the exact values. About half the bytes of the same data as JSON.
    """
    lines = []
    for key, value in data.items():
        if value == []:
            lines.append(f"{key}: none")
            continue
        if _empty(value):
            continue
        if isinstance(value, list) and all(isinstance(v, dict) for v in value):
            lines.append(f"{key}:")
            lines.extend("- " + _inline(v)[1:-1] for v in value)
        elif isinstance(value, dict):
            lines.append(f"{key}: " + _inline(value)[1:-1])
        else:
            lines.append(f"{key}: {_inline(value)}")
    return "\n".join(lines)


def compact_description(text: str) -> str:
    """A docstring as one paragraph per line: indentation and wrapped line breaks removed."""
    paragraphs = inspect.cleandoc(text).split("\n\n")
    return "\n".join(" ".join(p.split()) for p in paragraphs if p.strip())


BOUNDS = ("maximum", "minimum")
FAR = 10_000  # bounds this far out (world metres, pixel ids, scales) are no guide to a model


def compact_schema(schema: Any, in_properties: bool = False) -> Any:
    """A JSON schema without pydantic's titles, `additionalProperties: false` (the server
    still refuses unknown fields, naming them), model docstrings in `$defs` (their fields
    are described), length and item limits and bounds of 10^4 or more (still checked, with
    an error naming the limit, but no guide to calling a tool right) and defaults that are
    empty or false (what leaving an argument out means anyway), and with optional-or-null
    as just optional.

    `{"anyOf": [X, {"type": "null"}], "default": null}` becomes X: leaving the argument out
    means the same, and weaker adapters handle a plain type better than a nullable union.
    Property names are kept even when one is called "title".
    """
    if isinstance(schema, list):
        return [compact_schema(s) for s in schema]
    if not isinstance(schema, dict):
        return schema
    if in_properties:
        return {k: compact_schema(v) for k, v in schema.items()}
    out: dict[str, Any] = {}
    for key, value in schema.items():
        if (
            (key == "title" and isinstance(value, str))
            or (key == "additionalProperties" and value is False)
            or key in ("maxLength", "maxItems")
            or (key in BOUNDS and isinstance(value, int | float) and abs(value) >= FAR)
            or (key == "default" and (value == "" or value is False))
        ):
            continue
        if key == "$defs" and isinstance(value, dict):  # the fields say what matters
            value = {
                n: {k: v for k, v in d.items() if k != "description"} for n, d in value.items()
            }
        out[key] = compact_schema(value, in_properties=key in ("properties", "$defs"))
    options = out.get("anyOf")
    if (
        isinstance(options, list)
        and len(options) == 2
        and {"type": "null"} in options
        and out.get("default") is None
    ):
        (kept,) = [o for o in options if o != {"type": "null"}]
        del out["anyOf"]
        out.pop("default", None)
        out = {**kept, **out}
    return out


def strip_descriptions(schema: Any, in_properties: bool = False) -> Any:
    """`schema` without its "description" keywords (property names kept)."""
    if isinstance(schema, list):
        return [strip_descriptions(s) for s in schema]
    if not isinstance(schema, dict):
        return schema
    return {
        k: strip_descriptions(v, k in ("properties", "$defs") and not in_properties)
        for k, v in schema.items()
        if in_properties or k != "description"
    }
