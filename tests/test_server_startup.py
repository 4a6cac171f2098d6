"""Start-up work in the background: the handshake does not wait, the first calls do and say so.

The timing itself (initialize and tools/list within 0.5 s of launch) is measured by
`python -m glmap_tools.bench startup`, not here.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading

import anyio
import pytest
from mcp import Client

from glmap_tools.app.background import EMBEDDER, KERNELS, Background, BackgroundEmbedder
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.server import build_server
from tests.test_server_fixtures import config, frame_args

pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


async def test_tools_list_answers_while_loading_and_the_first_call_waits_saying_so(tmp_path):
    server = build_server(config(tmp_path))
    release = threading.Event()
    server.background.start(EMBEDDER, lambda: release.wait(30))  # an embedder still loading
    messages: list[str] = []

    async def progress(_: float, __: float | None, message: str | None) -> None:
        messages.append(message or "")

    async with Client(server) as client:
        with anyio.fail_after(10):
            assert "find_instance" in {t.name for t in (await client.list_tools()).tools}
        result: list = []

        async def call() -> None:
            result.append(
                await client.call_tool("find_instance", {"query": "a chair"}, None, progress)
            )

        with anyio.fail_after(30):
            async with anyio.create_task_group() as tg:
                tg.start_soon(call)
                while not messages:
                    await anyio.sleep(0.02)
                assert not result  # still waiting for the "embedder"
                release.set()
    assert "find_instance waits: the server is still loading the text embedder" in messages[0]
    assert not result[0].is_error


async def test_listing_maps_and_reading_the_map_answer_while_the_embedder_loads(tmp_path):
    server = build_server(config(tmp_path))
    release = threading.Event()
    server.background.start(EMBEDDER, lambda: release.wait(30))  # an embedder still loading
    try:
        async with Client(server) as client:
            with anyio.fail_after(10):
                listed = await client.call_tool("list_maps", {})
                summary = await client.call_tool("map_summary", {"include_image": False})
                near = await client.call_tool("what_is_at", {"x": 0.0, "y": 0.0})
        assert not listed.is_error and not summary.is_error and not near.is_error
    finally:
        release.set()


async def test_a_failed_embedder_load_is_reported_by_calls_and_failed_kernels_are_not_fatal(
    tmp_path,
):
    server = build_server(config(tmp_path))

    def broken(what: str) -> None:
        raise RuntimeError(f"{what} unreadable")

    server.background.start(KERNELS, lambda: broken("kernel cache"))
    async with Client(server) as client:
        observed = await client.call_tool("observe_frame", frame_args())  # compiles on use
        server.background.start(EMBEDDER, lambda: broken("model file"))
        found = await client.call_tool("find_instance", {"query": "a chair"})
    assert not observed.is_error
    assert found.is_error and "loading the text embedder failed: model file unreadable" in (
        found.content[0].text
    )


def test_the_background_embedder_has_its_models_name_and_size_before_it_loads():
    background = Background()
    gate = threading.Event()

    def load() -> HashingEmbedder:
        gate.wait(10)
        return HashingEmbedder(64)

    task = background.start(EMBEDDER, load)
    embedder = BackgroundEmbedder(task, HashingEmbedder(64))
    assert (embedder.name, embedder.dim) == ("hashing-64", 64) and not task.done
    assert embedder.default_tau_match == HashingEmbedder.default_tau_match
    gate.set()
    assert embedder.embed(["a chair"]).shape == (1, 64)


def test_building_the_server_imports_none_of_the_slow_libraries(tmp_path):
    """What `glmap-mcp` runs before it can answer tools/list stays light (numpy, cv2, mcp)."""
    code = (
        "import sys\n"
        "from glmap_tools.server import ServerConfig, build_server\n"
        f"build_server(ServerConfig(maps_dir={str(tmp_path)!r}))\n"
        "slow = ('scipy', 'numba', 'torch', 'sentence_transformers', 'skfmm', 'pyrender')\n"
        "print(' '.join(m for m in slow if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert done.stdout.strip() == "", done.stdout


def test_start_up_work_waits_for_the_handshake_then_runs():
    background = Background(hold_s=30.0)
    ran = threading.Event()
    task = background.start(KERNELS, ran.set)
    assert not ran.wait(0.3)  # held: the handshake gets the CPU
    background.release()
    assert ran.wait(10) and task.wait() is None
    unreleased = Background(hold_s=0.2).start(KERNELS, lambda: 7)
    assert unreleased.wait() == 7  # nobody asked for tools: the hold ends by itself


async def test_tools_list_or_a_call_releases_the_start_up_work(tmp_path):
    for first in ("tools/list", "call"):
        server = build_server(config(tmp_path / first.replace("/", "-")))
        ran = threading.Event()
        server.background.start("probe", ran.set)
        async with Client(server) as client:
            assert not ran.is_set()
            if first == "tools/list":
                await client.list_tools()
            else:
                await client.call_tool("list_maps", {})
            with anyio.fail_after(10):
                while not ran.is_set():
                    await anyio.sleep(0.01)


HEAVY = (
    "mcp",  # the SDK: the relay answers while it imports
    "trimesh",
    "pyrender",
    "OpenGL",
    "numba",
    "scipy",
    "torch",
    "transformers",
    "sentence_transformers",
    "gymnasium",
    "glmap_tools.sim.episodes",
    "glmap_tools.worlds.scene_dirs",
    "glmap_tools.gaussians",
    "glmap_tools.language.embed",
)
LAUNCH_PROBE = """
import json, sys
import glmap_tools.server.handshake as handshake

def probe():  # stands in for the relay: what the launch loaded before it could answer
    heavy = sys.argv[1].split(",")
    print(json.dumps([m for m in heavy if m in sys.modules]))
    raise SystemExit(0)

handshake.start_relay = probe
from glmap_tools.server.cli import main
raise SystemExit(main(sys.argv[2:]) or 3)  # 3: the launch never reached the relay
"""


@pytest.mark.parametrize(
    "args",
    [[], ["--embedder", "hashing", "--no-warm-up"], ["--map", "demo"]],
    ids=["defaults", "hashing", "map"],
)
def test_the_stdio_launch_reaches_the_handshake_relay_before_any_heavy_import(tmp_path, args):
    """`glmap-mcp` parses its arguments, checks them and starts the relay that answers
    initialize and tools/list; none of that may load the SDK, the simulator, the renderer,
    numba's kernels or the embedder (they load after, in the background)."""
    argv = ["--maps-dir", str(tmp_path), *args]
    done = subprocess.run(
        [sys.executable, "-c", LAUNCH_PROBE, ",".join(HEAVY), *argv],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout) == [], f"imported before the relay: {done.stdout}"


def test_scene_folders_are_still_read_at_launch_when_given(tmp_path):
    from glmap_tools.errors import GLMapError
    from glmap_tools.server.cli import build_parser, config_from_args

    args = build_parser().parse_args(["--scenes-dir", f"mine={tmp_path}"])
    with pytest.raises(GLMapError, match="no scene"):
        config_from_args(args)
    assert config_from_args(build_parser().parse_args([])).scene_dirs == {}


def test_the_kernel_warm_up_reaches_the_fits_merge_and_the_fusions_remerge(monkeypatch):
    # `glmap-mcp --prepare` fills numba's cache with what warm_kernels runs: a warm-up whose
    # instance is too small to merge leaves the merge kernels to compile in the first
    # observe_frame of every server (~40 s).
    from glmap_tools.app.background import warm_kernels
    from glmap_tools.gaussians import _estimator_fast

    found: dict[str, list[int]] = {"fit": [], "remerge": []}

    def counted(name, fn):  # type: ignore[no-untyped-def]
        def wrapper(*args, **kwargs):  # type: ignore[no-untyped-def]
            pairs = fn(*args, **kwargs)
            found[name].append(len(pairs))
            return pairs

        return wrapper

    monkeypatch.setattr(_estimator_fast, "_fit_pairs", counted("fit", _estimator_fast._fit_pairs))
    monkeypatch.setattr(
        _estimator_fast,
        "sorted_mergeable_pairs",
        counted("remerge", _estimator_fast.sorted_mergeable_pairs),
    )
    warm_kernels()
    assert max(found["fit"], default=0) > 0, found  # the fit found mergeable pairs
    assert max(found["remerge"], default=0) > 0, found  # the fused unit's Gaussians merged


# A fresh process: warm the kernels as `glmap-mcp --prepare` and the server's start do, then
# play the tools' common calls; prints the (module, kernel, signature) the calls needed that
# the warm-up had not compiled or loaded.
UNWARMED_KERNELS = """
import asyncio, json, sys, tempfile
from pathlib import Path
from numba.core.registry import CPUDispatcher
from mcp import Client
from glmap_tools.app.background import warm_kernels
from glmap_tools.server import ServerConfig, build_server
from tests.test_server_fixtures import frame_args

def compiled():
    return {
        (name, attr, str(sig))
        for name, module in list(sys.modules.items()) if name.startswith("glmap_tools")
        for attr, value in list(vars(module).items()) if isinstance(value, CPUDispatcher)
        for sig in value.signatures
    }

CALLS = [
    ("sim_reset", {"episode": "tune/objectnav/s03-013"}),
    ("nav_step", {"actions": 3}),
    ("navigate_to", {"x": 15.43, "y": 3.93, "max_steps": 2}),
    ("observe_frame", frame_args()),
    ("find_instance", {"query": "a bed"}),
    ("render_view", {"target": "map", "x": 1.0, "y": 1.0}),
]

async def play():
    with tempfile.TemporaryDirectory() as tmp:
        config = ServerConfig(maps_dir=Path(tmp), embedder="hashing", warm_up=False)
        async with Client(build_server(config)) as client:
            for name, args in CALLS:
                result = await client.call_tool(name, args)
                assert not result.is_error, (name, result.content[0].text)

warm_kernels()
before = compiled()
asyncio.run(play())
print(json.dumps(sorted(compiled() - before)))
"""


@pytest.mark.slow  # a server process plays a short episode
def test_the_tools_common_calls_need_no_kernel_the_warm_up_left_out():
    # Each one left out compiles in the first call that needs it, after `--prepare` too.
    done = subprocess.run(
        [sys.executable, "-c", UNWARMED_KERNELS], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.splitlines()[-1]) == []


def test_the_layer_warm_up_compiles_what_a_frame_update_calls():
    # `glmap-mcp --prepare` compiles the layers' kernels in its second process while the
    # map's process compiles the estimator; a type the warm-up missed would compile again.
    import numpy as np

    from glmap_tools import synthetic
    from glmap_tools.app.background import warm_layer_kernels
    from glmap_tools.gaussians._combine_numba import combine_groups
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.map import GLMap, MapConfig
    from glmap_tools.map._occupancy_numba import mark_cells
    from glmap_tools.map._structure_numba import chunk_runs, frame_rows, merge_chunk, row_order
    from glmap_tools.nav import _sight_numba, _walls_numba
    from glmap_tools.nav.footprint import GoalMatch, in_clear_sight
    from glmap_tools.nav.perceive import walls_of

    kernels = (mark_cells, frame_rows, row_order, chunk_runs, merge_chunk, combine_groups,
               _walls_numba.count_means, _walls_numba.cell_extent, _walls_numba.grow_counted,
               _sight_numba.clear_sight)  # fmt: skip
    warm_layer_kernels()
    warmed = [list(k.signatures) for k in kernels]
    boxes = synthetic.floor(2.0) + synthetic.chair(0.0, 0.0, object_id=1)
    glmap = GLMap(MapConfig(), embedder=HashingEmbedder())
    for shift in (0.0, 0.05):
        frame, ids = synthetic.view(boxes, (shift, -1.2, 1.1), (0.0, 0.0, 0.4), 128, 96)
        glmap.integrate(frame, synthetic.semantics(ids, {1: ("chair", "a red chair")}))
    assert len(glmap.structure) > 0 and len(glmap.instances) == 1
    # and what a decision reads: the walls and a line of sight to the chair
    occ = glmap.occupancy.to_dense()
    walls = walls_of(glmap, occ)
    assert walls is not None  # the floor and a chair: no wall, but the counts were read
    chair = GoalMatch(1, 1.0, 2, np.array([[0, 0], [1, 1]]) + np.array(occ.origin))
    in_clear_sight(chair, occ, np.array([[3, 3], [5, 9]]), walls)
    assert [list(k.signatures) for k in kernels] == warmed


def test_the_halves_warm_up_compiles_what_a_frame_sized_fit_calls():
    # `glmap-mcp --prepare` compiles the two-thread kernels beside the map's process; a type
    # it missed would compile in the first frame-sized fit of every server.
    import numpy as np

    from glmap_tools.app.background import warm_halves_kernels
    from glmap_tools.gaussians import _estimator_numba, _estimator_voxels
    from glmap_tools.gaussians._estimator_fast import fit_fast
    from glmap_tools.gaussians.config import EstimatorConfig
    from glmap_tools.gaussians.estimator import validate_cloud

    kernels = (_estimator_voxels.scan_cloud_halves, _estimator_voxels.voxelize_halves,
               _estimator_numba.voxel_moments_split)  # fmt: skip
    warm_halves_kernels()
    warmed = [list(k.signatures) for k in kernels]
    assert all(warmed)
    rng = np.random.default_rng(1)
    plane = np.c_[rng.uniform(0, 1.0, (50_000, 2)), rng.normal(0, 0.003, 50_000)]
    points, colors, lo = validate_cloud(plane, rng.uniform(0, 1, (50_000, 3)), 0.015)
    _estimator_voxels.scan_cloud_halves(points, colors)  # as `scan` calls it from 40k points
    fit_fast(points, colors, EstimatorConfig(voxel_size=0.015), lo, halves=True)
    assert [list(k.signatures) for k in kernels] == warmed


def test_the_wide_cloud_warm_up_takes_the_hashed_grids_path(monkeypatch):
    from glmap_tools.app.background import warm_wide_cloud_kernels
    from glmap_tools.gaussians import _estimator_fast

    calls: list[int] = []
    real = _estimator_fast.grid_pairs

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(_estimator_fast, "grid_pairs", counted)
    warm_wide_cloud_kernels()
    assert calls
