"""`python -m glmap_tools.bench pending`: server memory with every session's frames pending.

Issue 27 item 2: each unlabelled 2048 x 2048 frame kept for label_segments took ~245 MB
(a full-size bool mask per segment), and two sessions took a server from 676 MB to 5 GB.
Issue 41 item 3: with calls in flight (8 sessions, 2048 x 2048 frames, 8 at once) the
server grew by 2257 MiB: every call decoded its frame at once, and a refused frame's arrays
stayed (reference cycles through its traceback) until the next garbage collection.

Here `--sessions` sessions of one in-process server (the tools as the MCP server runs them)
each send `--frames` unannotated `--size` x `--size` frames (more than a session may keep),
`--in-flight` calls at a time, and label none. Printed: the bytes the pending frames hold,
the most frame work (`app.memory.FrameWork`) held at once, the process's resident memory
before, at its peak and after every session started a new map, and how many frames were
refused. Targets: the pending frames hold at most their cap (MAX_SERVER_PENDING_BYTES),
frames at work at most theirs (MAX_FRAME_WORK_BYTES, or one larger frame); resident memory
grows by at most the two caps plus MAPS_ALLOWANCE (the sessions' maps, which hold the
frames' geometry); a new map lets go of the frames, and the memory goes back to the system
(a quarter of the pending cap at most remains).
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from glmap_tools import synthetic as sy
from glmap_tools.app import memory
from glmap_tools.app.frames import observe_arguments
from glmap_tools.app.tools_perception import pending_frames
from glmap_tools.bench._args import MAX_SIDE, whole
from glmap_tools.bench.report import Report
from glmap_tools.perception import pending
from glmap_tools.server import ServerConfig
from glmap_tools.toolset import Toolset

MIB = 1 << 20
MAPS_ALLOWANCE = 256 * MIB  # the sessions' maps and the interpreter's own growth


def rss_mib() -> tuple[float, float]:
    """(resident, peak resident) MiB of this process (Linux /proc; 0 elsewhere)."""
    now = peak = 0.0
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                now = int(line.split()[1]) / 1024
            elif line.startswith("VmHWM:"):
                peak = int(line.split()[1]) / 1024
    except OSError:
        pass
    return now, peak


def reset_peak() -> None:
    """Start VmHWM afresh (Linux >= 4.0: write 5 to clear_refs); no-op elsewhere."""
    with contextlib.suppress(OSError):
        Path("/proc/self/clear_refs").write_text("5")


def scene_arguments(size: int) -> dict[str, Any]:
    """observe_frame arguments (no annotations) of a `size` x `size` view of the test room."""

    boxes = sy.floor() + sy.chair(0.0, 0.5, object_id=1) + sy.table(1.3, 0.8, 2)
    boxes += sy.chair(-1.0, 1.0, object_id=3)
    frame, _ = sy.view(boxes, (0.3, -2.0, 1.4), (0.3, 0.8, 0.4), size, size)
    return observe_arguments(frame)


def main(argv: list[str] | None = None) -> int:
    args = _arguments(argv)

    report = Report("bench pending")
    cap = pending.MAX_SERVER_PENDING_BYTES / MIB
    per_frame = pending.pending_bytes(args.size, args.size) / MIB
    report.info(
        f"{args.sessions} sessions x {args.frames} unannotated {args.size}x{args.size} frames "
        f"({per_frame:.1f} MiB each pending), {args.in_flight} calls in flight; caps "
        f"{pending.MAX_SESSION_PENDING_BYTES / MIB:.0f} MiB a session, {cap:.0f} MiB in all"
    )
    call = scene_arguments(args.size)
    with tempfile.TemporaryDirectory() as tmp:
        config = ServerConfig(maps_dir=Path(tmp), embedder="hashing", warm_up=False)
        with Toolset(config) as tools:
            registry = tools.state.registry
            warm, working = _working_memory(tools, call, per_frame)
            store = pending_frames(tools.state)
            base, _ = rss_mib()
            reset_peak()
            sessions = [registry.start_session() for _ in range(args.sessions - 1)] + [warm]
            counts, took = _rounds(
                tools, call, sessions, args.frames, args.in_flight, store, report
            )
            kept, refused = counts["kept"], counts["refused"]
            work_peak = memory.frame_work(tools.state).peak
            held = store.held() / MIB
            now, peak = rss_mib()
            for session in sessions:
                tools.call("new_map", {"session": session.handle})
            after, _ = rss_mib()
            released = store.held() / MIB
    report.info(
        f"{kept} frames kept, {refused} refused in {took:.1f} s; resident memory {base:.0f} MiB "
        f"before, {peak:.0f} MiB at the peak, {now:.0f} MiB at the end, {after:.0f} MiB after "
        f"new_map in every session; one call's working memory {working:.0f} MiB; frame work "
        f"held at most {work_peak / MIB:.0f} MiB at once"
    )
    report.check("bytes the pending frames hold", held, "<=", cap, "MiB")
    work_cap = max(memory.MAX_FRAME_WORK_BYTES, memory.frame_work_bytes(args.size, args.size))
    report.check("frame work held at once", work_peak / MIB, "<=", work_cap / MIB, "MiB")
    # Beside the pending frames and the frames at work: the sessions' maps (their geometry).
    bound = (pending.MAX_SERVER_PENDING_BYTES + work_cap + MAPS_ALLOWANCE) / MIB
    report.check("peak resident growth", peak - base, "<=", bound, "MiB")
    report.check("pending bytes after new_map", released, "<=", 1.0, "MiB")
    report.check("resident growth after new_map", after - base, "<=", 0.25 * cap, "MiB")
    return report.finish()


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    """The command line of `python -m glmap_tools.bench pending`."""
    parser = argparse.ArgumentParser(prog="python -m glmap_tools.bench pending")
    parser.add_argument("--sessions", type=whole(1, 1000), default=32)
    parser.add_argument("--frames", type=whole(1, 10_000), default=pending.MAX_PENDING_FRAMES)
    parser.add_argument(
        "--size", type=whole(1, MAX_SIDE), default=1024, help="frame width and height (px)"
    )
    parser.add_argument(
        "--in-flight",
        type=whole(1, 64),
        default=1,
        help="observe_frame calls sent at once (threads)",
    )
    return parser.parse_args(argv)


def _working_memory(tools: Toolset, call: dict[str, Any], per_frame: float) -> tuple[Any, float]:
    """Warm-up, in a session of its own: one frame observed and labelled, to measure one
    call's working memory. (That session, the working memory in MiB beyond the frame.)"""
    warm = tools.state.registry.start_session()
    tools.call("observe_frame", {**call, "session": warm.handle})
    tools.call("new_map", {"session": warm.handle})
    base, _ = rss_mib()
    reset_peak()
    res = tools.call("observe_frame", {**call, "session": warm.handle})
    _, warm_peak = rss_mib()
    working = max(0.0, warm_peak - base - per_frame)
    tools.call("new_map", {"session": warm.handle})
    del res
    return warm, working


def _rounds(
    tools: Toolset,
    call: dict[str, Any],
    sessions: list[Any],
    frames: int,
    in_flight: int,
    store: pending.PendingFrames,
    report: Report,
) -> tuple[dict[str, int], float]:
    """Every session sends `frames` frames, one a round, `in_flight` calls at once, each
    round reported: ({"kept": n, "refused": n}, seconds)."""
    counts = {"kept": 0, "refused": 0}
    lock = threading.Lock()

    def observe(session: Any) -> None:
        try:
            tools.call("observe_frame", {**call, "session": session.handle})
            outcome = "kept"
        except pending.LimitError:
            outcome = "refused"
        with lock:
            counts[outcome] += 1

    start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=in_flight) as workers:
        for k in range(frames):
            list(workers.map(observe, sessions))  # each session once per round
            report.info(
                f"round {k + 1}: pending frames hold {store.held() / MIB:.0f} MiB, "
                f"resident {rss_mib()[0]:.0f} MiB, {counts['refused']} frames refused "
                "so far"
            )
    took = time.perf_counter() - start
    return counts, took


if __name__ == "__main__":
    raise SystemExit(main())
