"""Frames in flight are bounded in bytes (issue 41 item 3): calls wait their turn."""

from __future__ import annotations

import anyio
import pytest
from mcp import Client

from glmap_tools.app.frames import observe_arguments
from glmap_tools.app.memory import FrameWork, frame_work, frame_work_bytes
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, view

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_a_frame_that_does_not_fit_waits_until_an_earlier_one_is_done():
    work = FrameWork(limit=100)
    order: list[str] = []
    first_in = anyio.Event()
    release_first = anyio.Event()

    async def first() -> None:
        async with work.hold(60):
            order.append("first in")
            first_in.set()
            await release_first.wait()
            order.append("first out")

    async def second() -> None:
        await first_in.wait()
        async with work.hold(60):
            order.append("second in")
            assert work.used == 60

    async with anyio.create_task_group() as tasks:
        tasks.start_soon(first)
        tasks.start_soon(second)
        await first_in.wait()
        await anyio.wait_all_tasks_blocked()
        assert order == ["first in"] and work.used == 60  # the second waits
        release_first.set()
    assert order == ["first in", "first out", "second in"]
    assert work.used == 0 and work.peak == 60


async def test_frames_that_fit_together_run_together_and_a_huge_one_runs_alone():
    work = FrameWork(limit=100)
    async with work.hold(40), work.hold(40):
        assert work.used == 80
    async with work.hold(500):  # larger than the limit: admitted when nothing else runs
        assert work.used == 500
    assert work.used == 0


async def test_waiters_are_admitted_in_arrival_order_and_a_cancelled_one_leaves_no_trace():
    work = FrameWork(limit=100)
    admitted: list[str] = []
    hold_big = anyio.Event()

    async def big() -> None:
        async with work.hold(90):
            await hold_big.wait()

    async def waiter(name: str, nbytes: int) -> None:
        async with work.hold(nbytes):
            admitted.append(name)

    async with anyio.create_task_group() as tasks:
        tasks.start_soon(big)
        await anyio.wait_all_tasks_blocked()
        with anyio.CancelScope() as doomed:
            async with anyio.create_task_group() as inner:
                inner.start_soon(waiter, "cancelled", 50)
                await anyio.wait_all_tasks_blocked()
                doomed.cancel()
        tasks.start_soon(waiter, "large", 80)
        await anyio.wait_all_tasks_blocked()
        tasks.start_soon(waiter, "small", 5)  # fits now, but "large" came first
        await anyio.wait_all_tasks_blocked()
        assert admitted == []
        hold_big.set()
    assert admitted == ["large", "small"]
    assert work.used == 0


async def test_concurrent_observe_frame_calls_never_hold_more_frame_work_than_the_limit(tmp_path):
    frame, _ = view((0.0, -2.6, 1.4), 320, 240)
    args = observe_arguments(frame)  # unannotated: segmented and left pending
    one = frame_work_bytes(320, 240)
    server = build_server(config(tmp_path))
    async with Client(server) as client:
        state = server.state
        assert state is not None
        work = frame_work(state)
        work.limit = one + one // 2  # room for one frame at a time

        results = []

        async def observe() -> None:
            results.append(await client.call_tool("observe_frame", args))

        async with anyio.create_task_group() as tasks:
            for _ in range(4):
                tasks.start_soon(observe)
    assert [r.is_error for r in results] == [False] * 4, results[0].content[0].text
    assert work.peak == one  # four calls in flight, one frame at work at a time
    assert work.used == 0
