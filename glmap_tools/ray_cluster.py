"""Connecting to Ray: where `--ray-address` points, whether a Ray server answers there, and
`ray.init` on it. Episodes (`eval.ray_engine`) and many-folder builds (`ingest.engines`)
both run on it, so it sits below both.

`--ray-address` takes what `ray.init` takes: 'local' (start a Ray instance on this machine),
'auto' (the cluster started here with `ray start --head`), 'HOST:PORT' (a cluster's GCS
address, from a node of that cluster) or 'ray://HOST:PORT' (Ray Client, from anywhere).
Before `ray.init`, the address is probed with the first call Ray itself makes, so one that
does not answer fails within `CONNECT_TIMEOUT_S`, not after Ray's own retries (20 s and
more).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from glmap_tools.errors import GLMapError, InvalidInputError

# Imports inside functions stay there: grpc loads on first use: `glmap` imports every command
# module to build its parser; optional: ray.

CONNECT_TIMEOUT_S = 5.0


def _current_cluster_file() -> Path:
    """Where `ray start --head` records the address of the cluster it started."""
    return Path(os.environ.get("RAY_TMPDIR", "/tmp")) / "ray" / "ray_current_cluster"


class RayUnavailableError(GLMapError):
    """Ray is not installed, or the Ray address given does not answer."""


def import_ray() -> Any:
    """The ray module.

    Raises:
        RayUnavailableError: Ray is not installed.
    """
    try:
        import ray
    except ImportError as exc:
        raise RayUnavailableError(
            "--ray-address needs Ray; install it with `pip install 'glmap-tools[ray]'`."
        ) from exc
    return ray


def resolve_address(address: str) -> tuple[str, int] | None:
    """The (host, port) to probe for `address`, or None for 'local' (nothing to reach).

    Raises:
        RayUnavailableError: 'auto' with no cluster started on this machine.
        InvalidInputError: an address that is not 'local', 'auto', HOST:PORT or ray://HOST:PORT.
    """
    if address == "local":
        return None
    if address == "auto":
        found = os.environ.get("RAY_ADDRESS", "")
        if not found and _current_cluster_file().is_file():
            found = _current_cluster_file().read_text(encoding="utf-8").strip()
        if not found or found in ("auto", "local"):
            raise RayUnavailableError(
                "--ray-address auto: no Ray cluster was started on this machine; start one "
                "with `ray start --head`, or give HOST:PORT or ray://HOST:PORT."
            )
        address = found
    rest = address.removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise InvalidInputError(
            f"--ray-address {address!r} is not 'local', 'auto', HOST:PORT or ray://HOST:PORT "
            "(e.g. ray://10.0.0.5:10001)."
        )
    return host.strip("[]"), int(port)


# What `ray.init` asks first: the GCS for its cluster id, a Ray Client server for its info.
GCS_METHOD = "/ray.rpc.NodeInfoGcsService/GetClusterId"
CLIENT_METHOD = "/ray.rpc.RayletDriver/ClusterInfo"


def _unavailable(address: str, host: str, port: int, why: str, timeout_s: float) -> Exception:
    return RayUnavailableError(
        f"Ray address {address!r} does not answer ({why}; waited at most {timeout_s:.0f} s "
        f"for {host}:{port}); start the cluster (`ray start --head`) or check host and port "
        "(the GCS is usually HOST:6379, Ray Client ray://HOST:10001)."
    )


def check_address(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Fail fast unless a Ray server answers at `address` within `timeout_s`.

    An open TCP port proves little (a proxy or another service may hold it), so the probe
    makes the first call `ray.init` makes, with an empty request: a Ray GCS or Ray Client
    server answers it (OK, or UNAUTHENTICATED when the cluster wants its token, which
    `ray.init` then supplies); refusal, silence or a non-Ray answer fail.

    Raises:
        RayUnavailableError: no Ray server answered in time.
    """
    target = resolve_address(address)
    if target is None:
        return
    host, port = target
    try:
        import grpc  # comes with Ray's client extra
    except ImportError as exc:
        raise RayUnavailableError(
            "--ray-address needs Ray; install it with `pip install 'glmap-tools[ray]'`."
        ) from exc

    method = CLIENT_METHOD if address.startswith("ray://") else GCS_METHOD
    answered = {grpc.StatusCode.UNAUTHENTICATED, grpc.StatusCode.PERMISSION_DENIED}
    channel = grpc.insecure_channel(f"{host}:{port}")
    try:
        channel.unary_unary(method)(b"", timeout=timeout_s)
    except grpc.RpcError as exc:
        code = exc.code()  # type: ignore[attr-defined]
        if code not in answered:
            why = {
                grpc.StatusCode.DEADLINE_EXCEEDED: "no answer",
                grpc.StatusCode.UNAVAILABLE: "connection failed",
                grpc.StatusCode.UNIMPLEMENTED: "something answered, but not a Ray server",
            }.get(code, str(code))
            raise _unavailable(address, host, port, why, timeout_s) from None
    finally:
        channel.close()


def connect(address: str, local_cpus: int) -> tuple[Any, bool]:
    """(the ray module, whether this call started Ray): Ray at `address`; 'local' starts an
    instance with `local_cpus` CPUs; one already running in this process is used as it is.

    Raises:
        RayUnavailableError: Ray missing or the address not answering (within 10 s).
    """
    ray = import_ray()
    check_address(address)
    started_here = not ray.is_initialized()
    if started_here:
        kw: dict[str, Any] = {"log_to_driver": False}
        if address == "local":
            kw.update(num_cpus=max(1, local_cpus), include_dashboard=False)
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        ray.init(address=address, **kw)
    return ray, started_here
