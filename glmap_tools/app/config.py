"""`ServerConfig`: every setting of the MCP server (maps folder, embedder, input limits)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from glmap_tools.errors import InvalidInputError
from glmap_tools.language.backends import LLMSettings
from glmap_tools.map.config import MapConfig

# Imports inside functions stay there: gymnasium, numba, scipy, sim.episodes, trimesh,
# worlds.scene_dirs load on first use: `glmap-mcp` answers the handshake before they load (the
# launch path); build_server stays light (test_server_startup): the server loads them in the
# background or on first use.

# HTTP limits (glmap_tools.server.http); here so the command line needs no uvicorn import.
REQUEST_TIMEOUT_S = 10.0
MAX_CONNECTIONS = 64

EmbedderName = Literal["minilm", "hashing"]
SimPerception = Literal["auto", "gt", "detector"]
EMBEDDERS: tuple[str, ...] = ("minilm", "hashing")

MIB = 1024 * 1024
MAX_THREADS = 1024  # compute_threads (BLAS and torch take a C int)
# JSON envelope, pose, intrinsics and annotation labels on top of the base64 payload.
HTTP_BODY_OVERHEAD = 1 * MIB


def default_maps_dir() -> Path:
    """`$GLMAP_MAPS_DIR`, else `~/.glmap/maps`."""
    env = os.environ.get("GLMAP_MAPS_DIR")
    return Path(env).expanduser() if env else Path.home() / ".glmap" / "maps"


@dataclass(frozen=True)
class ServerConfig:
    """Settings of one MCP server process.

    Attributes:
        maps_dir: the only folder map files are read from or written to (created if missing).
        embedder: text embedder, 'minilm' (bundled all-MiniLM-L6-v2) or 'hashing' (fast,
            deterministic, less accurate; for tests and benchmarks).
        map_config: settings of every new map (saved maps keep their own).
        max_frame_bytes: the most bytes of encoded files (RGB + depth + mask) one
            observe_frame call may carry; the HTTP body limit is derived from it.
        max_frame_pixels: the most pixels of one observed image (checked before decoding).
        file_roots: folders whose files observe_frame may read by path; None = any local
            file, () = no file paths at all (base64 only).
        max_sessions: client sessions kept at once; the least recently used one is
            dropped (its unsaved map with it) when a new one would exceed this, if it has
            been idle for `session_protect_s`; otherwise the new session is refused.
        session_protect_s: a session used within this many seconds is never dropped to
            make room, so one client starting sessions cannot drop others' maps.
        render_size: default (width, height) of render_view images.
        warm_up: render once in the lifespan so the first render_view is not slowed by
            JIT compilation.
        sim_size: (width, height) of the simulator's camera images.
        sim_max_steps: actions per simulator episode before it is cut off.
        sim_perception: the simulator's perception: 'gt' (exact), 'detector' (errs like an
            open-vocabulary detector and a captioner, `sim/detector.py`) or 'auto' (the
            split's own: 'detector' for the houses split, else 'gt').
        compute_threads: BLAS and torch threads while the server runs (None: leave the
            process as it is); 1 keeps latency low and steady when calls overlap.
        llm: the language backends: text merger and f_S scorer (offline by default; "llm"
            uses an Ollama model, see docs/own_model.md).
        map_name: `glmap-mcp --map NAME`: the saved map the default session is pinned to,
            shared with every process started with the same name (see
            glmap_tools.app.persist); None: the default session starts on a scratch map.
        map_wait_s: how long a tool call waits for the map of `map_name` while another
            process holds it, before failing.
        scene_dirs: scene folders of one's own by name (`glmap-mcp --scenes-dir NAME=DIR`,
            `glmap_tools.worlds.scene_dirs`): sim_reset plays their episodes by id,
            '<name>/<task>/<scene>-<index>', like those of the built-in splits.
    """

    maps_dir: Path = field(default_factory=default_maps_dir)
    embedder: EmbedderName = "minilm"
    map_config: MapConfig = field(default_factory=MapConfig)
    max_frame_bytes: int = 24 * MIB
    max_frame_pixels: int = 2048 * 2048
    file_roots: tuple[Path, ...] | None = None
    max_sessions: int = 32
    session_protect_s: float = 600.0
    render_size: tuple[int, int] = (320, 240)
    warm_up: bool = True
    sim_size: tuple[int, int] = (320, 240)
    sim_max_steps: int = 500
    sim_perception: SimPerception = "auto"
    compute_threads: int | None = 1
    llm: LLMSettings = field(default_factory=LLMSettings)
    map_name: str | None = None
    map_wait_s: float = 10.0
    scene_dirs: Mapping[str, Path] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # Absolute from the start: a relative folder would change meaning with the working
        # directory, and SQLite's read-only URI needs an absolute path.
        object.__setattr__(self, "maps_dir", Path(self.maps_dir).expanduser().absolute())
        if self.embedder not in EMBEDDERS:
            raise InvalidInputError(
                f"embedder={self.embedder!r} is not one of {list(EMBEDDERS)}; use 'minilm' "
                "(accurate) or 'hashing' (fast, for tests)."
            )
        if not (isinstance(self.max_frame_bytes, int) and self.max_frame_bytes >= 1024):
            raise InvalidInputError(
                f"max_frame_bytes={self.max_frame_bytes!r} must be an integer >= 1024."
            )
        if not (isinstance(self.max_frame_pixels, int) and self.max_frame_pixels >= 64):
            raise InvalidInputError(
                f"max_frame_pixels={self.max_frame_pixels!r} must be an integer >= 64."
            )
        if not (isinstance(self.max_sessions, int) and self.max_sessions >= 1):
            raise InvalidInputError(f"max_sessions={self.max_sessions!r} must be an integer >= 1.")
        if not (
            isinstance(self.session_protect_s, int | float) and 0 <= self.session_protect_s < 1e9
        ):
            raise InvalidInputError(
                f"session_protect_s={self.session_protect_s!r} must be a number of seconds >= 0."
            )
        w, h = self.render_size
        if not (16 <= w <= 2048 and 16 <= h <= 2048):
            raise InvalidInputError(
                f"render_size={self.render_size!r} must be (width, height) within 16..2048."
            )
        sw, sh = self.sim_size
        if not (32 <= sw <= 1920 and 32 <= sh <= 1440):
            raise InvalidInputError(
                f"sim_size={self.sim_size!r} must be (width, height) within 32..1920 x 32..1440."
            )
        if self.sim_perception not in ("auto", "gt", "detector"):
            raise InvalidInputError(
                f"sim_perception={self.sim_perception!r} is not one of 'auto', 'gt', 'detector'."
            )
        if not (isinstance(self.sim_max_steps, int) and self.sim_max_steps >= 1):
            raise InvalidInputError(f"sim_max_steps={self.sim_max_steps!r} must be >= 1.")
        if self.compute_threads is not None and not (
            isinstance(self.compute_threads, int) and 1 <= self.compute_threads <= MAX_THREADS
        ):
            raise InvalidInputError(
                f"compute_threads={self.compute_threads!r} must be an integer in 1..{MAX_THREADS} "
                "or None."
            )
        if self.map_name is not None:
            from glmap_tools.app.session import check_map_name

            stem = check_map_name(self.map_name, what="--map name")
            object.__setattr__(self, "map_name", stem)
        if not (isinstance(self.map_wait_s, int | float) and 0 <= self.map_wait_s <= 3600):
            raise InvalidInputError(
                f"map_wait_s={self.map_wait_s!r} must be a number of seconds within 0..3600."
            )
        if self.scene_dirs:
            from glmap_tools.worlds.scene_dirs import check_scene_dirs

            object.__setattr__(self, "scene_dirs", check_scene_dirs(self.scene_dirs))
        if self.file_roots is not None:
            roots = tuple(Path(r).expanduser().resolve() for r in self.file_roots)
            object.__setattr__(self, "file_roots", roots)

    @property
    def http_body_limit(self) -> int:
        """Bytes of one HTTP request body: base64 of `max_frame_bytes` plus the envelope."""
        return math.ceil(self.max_frame_bytes * 4 / 3) + HTTP_BODY_OVERHEAD
