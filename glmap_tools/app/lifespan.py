"""The app state's lifetime: opened with the start-up work in the background, closed once.

Both faces open it: the MCP server in its lifespan, a Toolset on `open()`.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from glmap_tools.app.background import (
    EMBEDDER,
    KERNELS,
    Background,
    BackgroundEmbedder,
    load_embedder,
    warm_kernels,
)
from glmap_tools.app.config import ServerConfig
from glmap_tools.app.runtime import AppState, PerceptionBackend
from glmap_tools.app.state import SessionRegistry
from glmap_tools.app.threads import limited_threads
from glmap_tools.errors import StoreError

if TYPE_CHECKING:
    from glmap_tools.language.embed import Embedder

# Imports inside functions stay there: language.embed load on first use: build_server stays light
# (test_server_startup): the server loads them in the background or on first use; the tools load
# before these do, in the server and the in-process toolset alike.

# Tools that render or integrate also wait for the kernels; every tool that may embed text
# waits for the embedder. These read files and stored numbers only: they never wait.
NO_WAIT_TOOLS = ("list_maps", "map_summary", "describe_unit", "what_is_at")
KERNEL_TOOLS = (
    "observe_frame",
    "render_view",
    "sim_reset",
    "sim_step",
    "navigate_to",
    "look_around",
    "nav_step",
    "label_segments",
)


def needed_tasks(name: str) -> tuple[str, ...]:
    """The start-up tasks a call of tool `name` waits for."""
    if name in NO_WAIT_TOOLS:
        return ()
    return (EMBEDDER, KERNELS) if name in KERNEL_TOOLS else (EMBEDDER,)


@contextmanager
def opened_state(
    config: ServerConfig, perception: PerceptionBackend | None, background: Background
) -> Iterator[AppState]:
    """The app state (embedder, sessions) for `config`, closed on exit.

    The MiniLM embedder loads on a background task unless it is the hashing one; the
    kernels warm up in the background when `config.warm_up`.
    """
    try:
        config.maps_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise StoreError(
            f"cannot create the maps folder {str(config.maps_dir)!r}: {exc.strerror or exc}. "
            "Create it, writable by the server, or choose another one (--maps-dir)."
        ) from None
    with limited_threads(config.compute_threads):
        embedder: Embedder
        if config.embedder == "hashing":
            embedder = load_embedder("hashing", None)
        else:
            from glmap_tools.language.minilm import MiniLMEmbedder

            task = background.start(
                EMBEDDER, lambda: load_embedder(config.embedder, config.compute_threads)
            )
            embedder = BackgroundEmbedder(task, MiniLMEmbedder)
        if config.warm_up:
            background.start(KERNELS, warm_kernels)
        registry = SessionRegistry(config, embedder)
        state = AppState(config, embedder, registry, perception, background)
        try:
            yield state
        finally:
            registry.close()
