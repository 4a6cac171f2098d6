"""`glmap-mcp` / `python -m glmap_tools.server`: serve GLMap over stdio or streamable HTTP.

HTTP binds 127.0.0.1 unless --host is given, and a non-loopback --host needs a bearer
token that every request must carry: from $GLMAP_MCP_TOKEN or --token-file (--token still
works but shows the token in the process list, and warns).

`--map NAME` is for clients that start a server process per tool call: every process
works on the saved map NAME and its simulator episode (glmap_tools.app.persist).
"""

from __future__ import annotations

import argparse
import hmac
import logging
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from glmap_tools.app.config import (
    MAX_CONNECTIONS,
    MIB,
    REQUEST_TIMEOUT_S,
    ServerConfig,
    default_maps_dir,
)
from glmap_tools.errors import GLMapError, InvalidInputError
from glmap_tools.language.backends import add_llm_arguments, settings_from_args
from glmap_tools.launch_env import set_thread_defaults
from glmap_tools.map import MapConfig
from glmap_tools.server.linger import SERVE_FLAG, relay_calls, serve_socket

# Imports inside functions stay there: anyio, cv2, gaussians, gymnasium, h11, mcp, numba, scipy,
# sim.episodes, trimesh, uvicorn, worlds.scene_dirs load on first use: `glmap-mcp` answers the
# handshake before they load (the launch path).

LOOPBACK = ("127.0.0.1", "localhost", "::1")
TOKEN_ENV = "GLMAP_MCP_TOKEN"
MCP_PATH = "/mcp"
MAX_LINGER_S = 86_400  # a day: a lingering server that never idles out is a leaked process


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="glmap-mcp",
        description="Serve a GLMap (Gaussian-Language Map) to MCP clients.",
    )
    _add_http_arguments(p)
    _add_map_arguments(p)
    _add_runtime_arguments(p)
    add_llm_arguments(p, sampling=True)
    _add_perception_arguments(p)
    from glmap_tools.cli_format import show_defaults

    return show_defaults(p)


def _add_http_arguments(p: argparse.ArgumentParser) -> None:
    """The transport, and HTTP's address, token and limits."""
    p.add_argument(
        "--transport", choices=["stdio", "streamable-http"], default="stdio", help="default stdio"
    )
    p.add_argument("--host", help="HTTP bind address (default 127.0.0.1; others need a token)")
    p.add_argument(
        "--port", type=int, default=8765, help="HTTP port (0 = any free port; default 8765)"
    )
    p.add_argument(
        "--token-file",
        type=Path,
        help=f"file holding the bearer token required on HTTP (default: ${TOKEN_ENV})",
    )
    p.add_argument(
        "--token", help=f"the bearer token itself: visible to other users; prefer ${TOKEN_ENV}"
    )
    p.add_argument(
        "--max-connections",
        type=int,
        default=MAX_CONNECTIONS,
        help="open HTTP connections at once; over it the oldest half-sent request is closed",
    )
    p.add_argument(
        "--request-timeout",
        type=float,
        default=REQUEST_TIMEOUT_S,
        help="seconds an HTTP request (headers and body) may take to arrive",
    )


def _add_map_arguments(p: argparse.ArgumentParser) -> None:
    """Where maps are saved and shared, and the scene folders played."""
    p.add_argument(
        "--maps-dir",
        type=Path,
        default=None,
        help=f"saved maps folder (default {default_maps_dir()})",
    )
    p.add_argument(
        "--map",
        metavar="NAME",
        help="work on the saved map NAME (created empty if absent) and keep the simulator "
        "episode in it, so processes started one per call share both; for clients that start "
        "a server per call (docs/mcp.md)",
    )
    p.add_argument(
        "--linger",
        type=float,
        metavar="SECONDS",
        help="with --map: keep one server running in the background until no call has come "
        "for SECONDS; each process a client starts per call relays to it (docs/mcp.md)",
    )
    p.add_argument(SERVE_FLAG, type=Path, help=argparse.SUPPRESS)
    p.add_argument(
        "--map-wait",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="how long a call waits while another process uses the --map map (default 10)",
    )
    p.add_argument(
        "--scenes-dir",
        action="append",
        default=[],
        metavar="[NAME=]DIR",
        help="a folder of <scene>/layout.json + <scene>/<task>.json whose episodes sim_reset "
        "plays as NAME/<task>/<scene>-<index> (repeatable; NAME: the folder's name)",
    )


def _add_runtime_arguments(p: argparse.ArgumentParser) -> None:
    """The embedder, frame and voxel sizes, threads, start-up and logging."""
    p.add_argument("--embedder", choices=["minilm", "hashing"], default="minilm")
    p.add_argument("--max-frame-mb", type=float, default=24.0, help="files per observed frame")
    p.add_argument(
        "--file-root",
        type=Path,
        action="append",
        help="folder observe_frame may read files from (repeatable); stdio default: any, "
        "HTTP default: none (base64 only)",
    )
    p.add_argument("--voxel-size", type=float, default=0.02, help="Gaussian voxel (m), 0.001-1")
    p.add_argument(
        "--threads",
        type=int,
        default=1,
        help="BLAS/torch threads (default 1: steady latency; 0 = the libraries' defaults)",
    )
    p.add_argument(
        "--no-warm-up",
        action="store_true",
        help="do not load the compiled kernels in the background at start (then on first use)",
    )
    p.add_argument(
        "--prepare",
        action="store_true",
        help="fill numba's kernel cache, load the embedder once and prepare the handshake "
        "answers (docs/mcp.md, Start-up), then exit (for setup)",
    )
    p.add_argument("--log-level", default="WARNING", choices=["DEBUG", "INFO", "WARNING", "ERROR"])


def _add_perception_arguments(p: argparse.ArgumentParser) -> None:
    """Perception of frames without annotations, and the simulator's."""
    g = p.add_argument_group("perception of frames without annotations")
    g.add_argument(
        "--perception",
        choices=["pending", "geometric", "geometric+mllm", "mllm"],
        default="pending",
        help="pending (= geometric): model-free segments the calling agent names with "
        "label_segments; "
        "geometric+mllm: an Ollama vision model names them; mllm: MLLM + GroundingDINO + SAM",
    )
    g.add_argument("--detector", type=Path, help="GroundingDINO model folder (--perception mllm)")
    p.add_argument(
        "--sim-perception",
        choices=["auto", "gt", "detector"],
        default="auto",
        help="the simulator's perception: exact (gt), a detector's errors (sim/design.md), "
        "or the split's own (auto: detector on the houses split)",
    )
    g.add_argument("--segmenter", type=Path, help="SAM model folder (--perception mllm)")


def config_from_args(args: argparse.Namespace) -> ServerConfig:
    """The ServerConfig the command line asks for."""
    # stdio serves the local user: any file; HTTP may serve others: base64 unless told.
    roots: tuple[Path, ...] | None = None if args.transport == "stdio" else ()
    if args.file_root:
        roots = tuple(args.file_root)
    return ServerConfig(
        maps_dir=args.maps_dir or default_maps_dir(),
        embedder=args.embedder,
        map_config=MapConfig(voxel_size=args.voxel_size),
        max_frame_bytes=_frame_bytes(args.max_frame_mb),
        file_roots=roots,
        warm_up=not args.no_warm_up,
        compute_threads=args.threads or None,
        llm=settings_from_args(args),
        map_name=args.map,
        map_wait_s=args.map_wait,
        scene_dirs=_scene_dirs(args.scenes_dir),
        sim_perception=args.sim_perception,
    )


def _frame_bytes(megabytes: float) -> int:
    """--max-frame-mb in bytes (ServerConfig checks its range)."""
    if not math.isfinite(megabytes):
        raise InvalidInputError(f"--max-frame-mb {megabytes}: give megabytes, e.g. 24.")
    return int(megabytes * MIB)


def _scene_dirs(texts: list[str]) -> dict[str, Path]:
    """--scenes-dir values by name; a name given twice is refused.

    Without --scenes-dir nothing is imported: glmap_tools.worlds.scene_dirs pulls in trimesh and
    the episode generator (~0.8 s), which the handshake must not wait for.
    """
    if not texts:
        return {}
    from glmap_tools.worlds.scene_dirs import parse_scene_dir

    dirs: dict[str, Path] = {}
    for text in texts:
        name, folder = parse_scene_dir(text)
        if name in dirs:
            raise InvalidInputError(
                f"--scenes-dir name {name!r} is given twice; name them NAME=DIR apart."
            )
        dirs[name] = folder
    return dirs


def check_pinned_map(config: ServerConfig) -> None:
    """Refuse at launch a --map file that is not a map or was made with other settings.

    Reads only the file's meta table (milliseconds), so the handshake is not delayed.

    Raises:
        StoreError: see glmap_tools.app.persist.check_saved_map.
    """
    if config.map_name is None:
        return
    from glmap_tools.app.persist import check_saved_map
    from glmap_tools.app.session import MAP_SUFFIX

    path = config.maps_dir / f"{config.map_name}{MAP_SUFFIX}"
    check_saved_map(path, config.map_name, config.map_config, config.embedder)


def build(config: ServerConfig, perception: Any) -> Any:
    """The server (its tool calls hold the --map lock when --map is given)."""
    from glmap_tools.server.build import build_server

    return build_server(config, perception)


class BearerAuth:
    """ASGI middleware: refuse HTTP requests without `Authorization: Bearer <token>`."""

    def __init__(self, app: Any, token: str) -> None:
        self.app = app
        self.expected = f"Bearer {token}".encode()

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] == "http":
            given = dict(scope.get("headers") or []).get(b"authorization", b"")
            if not hmac.compare_digest(given, self.expected):
                await send(
                    {
                        "type": "http.response.start",
                        "status": 401,
                        "headers": [
                            (b"content-type", b"text/plain"),
                            (b"www-authenticate", b"Bearer"),
                        ],
                    }
                )
                await send(
                    {"type": "http.response.body", "body": b"missing or wrong bearer token\n"}
                )
                return
        await self.app(scope, receive, send)


def serve_http(
    server: Any,
    config: ServerConfig,
    host: str,
    port: int,
    token: str | None,
    max_connections: int = MAX_CONNECTIONS,
    request_timeout: float = REQUEST_TIMEOUT_S,
) -> None:
    """Serve streamable HTTP on host:port; prints the URL on stderr once it accepts.

    Connections are capped and each request must arrive within `request_timeout` seconds
    (see glmap_tools.server.http); repeated uvicorn log lines are rate-limited.
    """
    import anyio
    import uvicorn

    from glmap_tools.server.http import guarded_protocol, listening_socket, quiet_repeats

    app = server.streamable_http_app(
        streamable_http_path=MCP_PATH, max_request_body_size=config.http_body_limit, host=host
    )
    asgi: Any = BearerAuth(app, token) if token else app
    sock = listening_socket(host, port)
    bound = sock.getsockname()[1]
    shown = f"[{host}]" if ":" in host else host
    quiet_repeats()
    uv = uvicorn.Server(
        uvicorn.Config(
            asgi,
            log_level="warning",
            lifespan="on",
            http=guarded_protocol(request_timeout, max_connections),
        )
    )
    print(f"glmap-mcp: serving http://{shown}:{bound}{MCP_PATH}", file=sys.stderr, flush=True)
    anyio.run(lambda: uv.serve(sockets=[sock]))


def read_token(args: argparse.Namespace, environ: Any = os.environ) -> str | None:
    """The bearer token: --token-file, else --token (with a warning), else $GLMAP_MCP_TOKEN.

    Raises:
        InvalidInputError: an unreadable or empty token file.
    """
    if args.token_file is not None:
        try:
            token = args.token_file.read_text(encoding="utf-8").strip()
        except (OSError, UnicodeDecodeError) as exc:
            why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
            raise InvalidInputError(
                f"--token-file {args.token_file.name!r} cannot be read ({why}); give a "
                "readable file holding the token."
            ) from None
        if not token:
            raise InvalidInputError(
                f"--token-file {args.token_file.name!r} is empty; write the token into it."
            )
        from glmap_tools.server.http import token_file_warning

        warning = token_file_warning(args.token_file)
        if warning is not None:
            print(warning, file=sys.stderr)
        return token
    if args.token:
        print(
            f"glmap-mcp: warning: --token shows the token in the process list; set "
            f"${TOKEN_ENV} or use --token-file instead.",
            file=sys.stderr,
        )
        return str(args.token)
    return environ.get(TOKEN_ENV) or None


def perception_from_args(args: argparse.Namespace) -> Any:
    """The perception backend of observe_frame frames without annotations, or None.

    None (--perception pending): the frame's segments come back pending and the calling
    agent names them with label_segments. geometric+mllm: an Ollama vision model names the
    segments; mllm: the paper's MLLM + GroundingDINO + SAM (local model folders).
    """
    if args.perception in ("pending", "geometric"):  # the segments wait for label_segments
        return None
    from glmap_tools.perception.backends import model_perception

    return model_perception(
        args.perception, settings_from_args(args), args.detector, args.segmenter
    )


def prepare() -> int:
    """Fill numba's cache, check the embedder loads and prepare the handshake answers
    (`glmap-mcp --prepare`, .ci/setup).

    Numba compiles on one core: the map's kernels compile in a second process while this
    one compiles the map layers' own, the renderer's and the simulator's, loads the embedder,
    compiles the estimator's paths for very wide clouds and (on two threads) for frame-sized
    ones, and prepares the handshake answers
    (servers of its own, started one after another on a thread).
    """
    from concurrent.futures import ThreadPoolExecutor

    from glmap_tools.app.background import (
        load_embedder,
        warm_halves_kernels,
        warm_layer_kernels,
        warm_view_and_sim_kernels,
        warm_wide_cloud_kernels,
    )
    from glmap_tools.server.handshake import answers_path, prepare_handshake

    start = time.perf_counter()
    map_kernels = subprocess.Popen([sys.executable, "-c", MAP_KERNELS_SCRIPT])
    with ThreadPoolExecutor(1) as pool:
        try:
            handshake = pool.submit(prepare_handshake)
            warm_layer_kernels()  # first: the map's process meets them after its estimator
            warm_view_and_sim_kernels()
            load_embedder("minilm", None).embed(["a chair"])
            warm_wide_cloud_kernels()  # while the map's process still compiles
            warm_halves_kernels()
        finally:
            map_kernels.wait()
        versions = handshake.result()
    if map_kernels.returncode != 0:
        print(
            "glmap-mcp: error: compiling the map's kernels failed (its error is above)",
            file=sys.stderr,
        )
        return 1
    print(f"glmap-mcp kernels ready in {time.perf_counter() - start:.1f} s (numba cache filled)")
    print(f"handshake answers prepared for {', '.join(versions)} in {answers_path()}")
    return 0


MAP_KERNELS_SCRIPT = "from glmap_tools.app.background import warm_map_kernels; warm_map_kernels()"


def linger_problem(args: argparse.Namespace) -> str | None:
    """What is wrong with `--linger` on this command line, if anything."""
    if args.linger is None:
        return f"{SERVE_FLAG} is glmap-mcp's own flag; use --linger." if args.serve_socket else None
    if not 0 < args.linger <= MAX_LINGER_S:
        return (
            f"--linger {args.linger:g}: give the seconds the server waits for a call, in "
            f"(0, {MAX_LINGER_S}]."
        )
    if args.map is None:
        return "--linger needs --map NAME: the map the calls share."
    if args.transport != "stdio":
        return "--linger is for stdio clients that start a server per call; an HTTP server lingers."
    return None


def main(argv: list[str] | None = None) -> int:
    set_thread_defaults()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(argv)

    logging.basicConfig(level=args.log_level, stream=sys.stderr)
    if args.prepare:
        return prepare()
    problem = linger_problem(args)
    if problem is not None:
        print(f"glmap-mcp: error: {problem}", file=sys.stderr)
        return 2
    try:
        token = read_token(args)
        config = config_from_args(args)
        if args.linger is not None and args.serve_socket is None:
            return relay_calls(argv)  # the client's process: a relay to the lingering server
        check_pinned_map(config)
        perception = perception_from_args(args)
    except GLMapError as exc:
        print(f"glmap-mcp: error: {exc}", file=sys.stderr)
        return 2
    if args.transport == "stdio":
        if args.host or args.token or args.token_file:
            print(
                "glmap-mcp: error: --host/--token/--token-file are for streamable-http.",
                file=sys.stderr,
            )
            return 2
        if args.serve_socket is not None:  # the lingering server, started by a relay
            serve_socket(build(config, perception), args.serve_socket, args.linger)
        else:
            from glmap_tools.server.handshake import start_relay

            relay = start_relay()  # answers the handshake while the SDK imports
            relay.serve(build(config, perception))
        # Stdin closed and every session closed (maps committed): leave without tearing
        # down torch and the numba/GL libraries, which took ~3-5 s; clients that launch a
        # server per call wait 2 s before killing it.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
    host = args.host or "127.0.0.1"
    if host not in LOOPBACK and not token:
        print(
            f"glmap-mcp: error: --host {host} exposes the server beyond this machine; give a "
            f"bearer token in ${TOKEN_ENV} or --token-file (clients send 'Authorization: "
            "Bearer <token>').",
            file=sys.stderr,
        )
        return 2
    serve_http(
        build(config, perception),
        config,
        host,
        args.port,
        token,
        max_connections=args.max_connections,
        request_timeout=args.request_timeout,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
