"""Poses, intrinsics and descriptions that would poison a map are refused at the boundary.

Through the library (GLMap.integrate, MapConfig) and through a real in-memory MCP client
session; after every refusal the map answers every query and its file is byte for byte
what it was.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcp import Client

from glmap_tools.app.inputs import MAX_GROUPS
from glmap_tools.errors import InvalidInputError
from glmap_tools.geometry import Pose
from glmap_tools.geometry.frame import RGBDFrame
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.text_merger import MAX_DESCRIPTION_CHARS
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.map.bounds import OutOfBoundsError, check_frame_bounds, frame_extent
from glmap_tools.perception.annotated import semantics_from_annotation
from glmap_tools.server import build_server
from tests.test_server_fixtures import OBJECTS, config, counts, frame_args, view

EYE = (0.0, -2.6, 1.4)


def moved(frame: RGBDFrame, offset: tuple[float, float, float]) -> RGBDFrame:
    """The same images seen from a camera shifted by `offset` metres."""
    m = frame.pose.matrix.copy()
    m[:3, 3] += offset
    return RGBDFrame(frame.rgb, frame.depth, frame.intrinsics, Pose(m))


def semantics_of(ids: np.ndarray):  # type: ignore[no-untyped-def]
    objects = [
        {"id": int(i), "label": OBJECTS[int(i)][0], "description": OBJECTS[int(i)][1]}
        for i in np.unique(ids)
        if i
    ]
    return semantics_from_annotation(ids, {"objects": objects})


def observed_map(path: Path, **config: Any) -> tuple[GLMap, bytes]:
    """A stored map of one view of the test scene, and its file's bytes."""
    glmap = GLMap.open(path, MapConfig(voxel_size=0.04, **config), embedder=HashingEmbedder())
    frame, ids = view(EYE)
    glmap.integrate(frame, semantics_of(ids))
    return glmap, path.read_bytes()


def state(glmap: GLMap) -> tuple[Any, ...]:
    s = glmap.summary()
    return s.frames, s.instances, s.regions, s.gaussians, s.bounds, len(glmap.trajectory)


# ---------------------------------------------------------------------- library


@pytest.mark.parametrize(
    ("offset", "message"),
    [
        ((2000.0, 0.0, 0.0), "world_limit"),  # beyond +-1 km
        ((0.0, 900.0, 0.0), "max_span"),  # a frame 900 m from the first one
        ((0.0, 0.0, 300.0), "max_span"),  # 300 m up
    ],
)
def test_a_frame_outside_the_world_is_refused_and_the_map_and_file_stay_as_they_were(
    tmp_path: Path, offset: tuple[float, float, float], message: str
) -> None:
    path = tmp_path / "flat.glmap"
    glmap, file_before = observed_map(path)
    before = state(glmap)
    frame, ids = view(EYE)
    with pytest.raises(OutOfBoundsError, match=message):
        glmap.integrate(moved(frame, offset), semantics_of(ids))
    assert state(glmap) == before
    assert path.read_bytes() == file_before
    # The map still answers, and another view inside the world is still taken.
    assert glmap.find_instances("a red wooden chair")[0].description == "a red wooden chair"
    assert glmap.units_at(0.0, 0.0, 0.5)
    glmap.integrate(moved(frame, (0.5, 0.0, 0.0)), semantics_of(ids))
    assert glmap.summary().frames == 2
    glmap.close()
    reopened = GLMap.open(path, embedder=HashingEmbedder())
    assert reopened.summary().frames == 2
    reopened.close()


def test_a_first_frame_far_from_the_origin_but_inside_the_world_is_accepted() -> None:
    glmap = GLMap(MapConfig(voxel_size=0.04), embedder=HashingEmbedder())
    frame, ids = view(EYE)
    glmap.integrate(moved(frame, (900.0, -900.0, 0.0)), semantics_of(ids))
    lo, hi = glmap.summary().bounds or ([0.0], [0.0])
    assert 890 < lo[0] < hi[0] < 910


def test_depth_reaching_beyond_the_world_limit_is_refused() -> None:
    cfg = MapConfig(voxel_size=0.04, max_range=500.0, world_limit=100.0)
    frame, _ = view(EYE)
    far = RGBDFrame(frame.rgb, np.full_like(frame.depth, 400.0), frame.intrinsics, frame.pose)
    with pytest.raises(OutOfBoundsError, match="points reach"):
        check_frame_bounds(far, cfg, [])
    lo, hi = frame_extent(far, cfg.max_range)
    assert hi[1] > 100.0  # the camera looks along +y


def test_the_frame_extent_is_the_box_of_its_back_projected_points() -> None:
    from glmap_tools.geometry import backproject

    frame, _ = view(EYE)
    lo, hi = frame_extent(frame, 5.0)
    points = backproject(frame.depth, frame.intrinsics, frame.pose, max_range=5.0).points
    np.testing.assert_allclose(lo, np.minimum(points.min(axis=0), frame.pose.translation))
    np.testing.assert_allclose(hi, np.maximum(points.max(axis=0), frame.pose.translation))


def test_the_view_box_holds_every_point_and_a_frame_near_a_bound_is_judged_by_them() -> None:
    from glmap_tools.map.bounds import frustum_extent

    frame, _ = view(EYE)
    lo, hi = frame_extent(frame, 5.0)
    view_lo, view_hi = frustum_extent(frame, 5.0)
    assert np.all(view_lo <= lo) and np.all(hi <= view_hi)
    # A world limit between the points' reach and the view box's: the frame is judged by
    # its points, not refused for what it could have seen.
    reach = float(np.max(np.abs(np.concatenate([lo, hi]))))
    box = float(np.max(np.abs(np.concatenate([view_lo, view_hi]))))
    assert reach < box
    check_frame_bounds(frame, MapConfig(voxel_size=0.04, world_limit=(reach + box) / 2), [])


@pytest.mark.parametrize(
    "bad",
    [
        {"world_limit": float("inf")},
        {"world_limit": -1.0},
        {"world_limit": 1e7},
        {"max_span": float("nan")},
        {"max_range": float("inf")},
    ],
)
def test_map_config_refuses_world_bounds_that_are_not_positive_finite(bad: dict) -> None:
    with pytest.raises(InvalidInputError, match=next(iter(bad))):
        MapConfig(**bad)


@pytest.mark.parametrize(
    "bad",
    [
        {"voxel_size": 1e20},  # asked the index grid for 166 PiB
        {"voxel_size": 1e-300},
        {"cell_size": 1e-6},
        {"cell_size": 5.0},
        {"structure_voxel": 1e-9},
    ],
)
def test_map_config_refuses_a_voxel_or_cell_edge_outside_its_range(bad: dict) -> None:
    name = next(iter(bad))
    with pytest.raises(InvalidInputError, match=rf"MapConfig.{name}=.* m must lie in \["):
        MapConfig(**bad)
    MapConfig(**{name: 0.05})  # in range


@pytest.mark.parametrize(
    ("bad", "said"),
    [
        ({"tau_s": "0.5"}, "MapConfig.tau_s='0.5' must be a cosine in [-1, 1]"),
        ({"obstacle_band": 0.5}, "MapConfig.obstacle_band=0.5 must be (low, high) metres"),
        ({"obstacle_band": ("a", 1)}, "MapConfig.obstacle_band=('a', 1) must be (low, high)"),
        ({"obstacle_band": []}, "MapConfig.obstacle_band=[] must be (low, high)"),
        ({"estimator": 0}, "MapConfig.estimator=0 must be a dict of EstimatorConfig settings"),
        ({"max_range": True}, "MapConfig.max_range=True must be a positive finite number"),
    ],
)
def test_map_config_refuses_a_setting_of_another_kind(bad: dict, said: str) -> None:
    with pytest.raises(InvalidInputError) as refused:
        MapConfig(**bad)
    assert said in str(refused.value)


def test_world_bounds_are_saved_with_the_config_and_default_for_older_maps() -> None:
    cfg = MapConfig(world_limit=250.0, max_span=80.0)
    assert MapConfig.from_dict(cfg.to_dict()) == cfg
    older = {k: v for k, v in MapConfig().to_dict().items() if k not in ("world_limit", "max_span")}
    assert (MapConfig.from_dict(older).world_limit, MapConfig.from_dict(older).max_span) == (
        1000.0,
        200.0,
    )


def test_a_description_over_the_limit_is_refused_where_annotations_are_read() -> None:
    _, ids = view(EYE)
    long = "a chair. " * (MAX_DESCRIPTION_CHARS // 9 + 1)
    with pytest.raises(InvalidInputError, match=f"limit is {MAX_DESCRIPTION_CHARS}"):
        semantics_from_annotation(ids, {"objects": [{"id": 1, "description": long}]})
    ok = long[:MAX_DESCRIPTION_CHARS]
    assert semantics_from_annotation(ids, {"objects": [{"id": 1, "description": ok}]}).objects


# ---------------------------------------------------------------------- MCP


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def _with(args: dict[str, Any], **change: Any) -> dict[str, Any]:
    out = copy.deepcopy(args)
    if "translate" in change:
        for k, d in enumerate(change["translate"]):
            out["pose"]["matrix"][k][3] += d
    if "intrinsics" in change:
        out["intrinsics"] = change["intrinsics"]
    return out


BAD_FRAMES = [
    ("a rigid pose 1e300 m away", {"translate": (1e300, 0.0, 0.0)}, "from the origin"),
    ("a pose 2 km away", {"translate": (2000.0, 0.0, 0.0)}, "world_limit"),
    ("a frame 900 m from the first", {"translate": (0.0, 900.0, 0.0)}, "max_span"),
    ("hfov 179.999 deg", {"intrinsics": {"hfov_deg": 179.999}}, "hfov_deg=179.999"),
    ("hfov 179.9999999 deg", {"intrinsics": {"hfov_deg": 179.9999999}}, "hfov_deg"),
    ("fx = 1e-300", {"intrinsics": {"fx": 1e-300, "fy": 100, "cx": 80, "cy": 60}}, "fx=1e-300"),
    ("cx = 1e300", {"intrinsics": {"fx": 100, "fy": 100, "cx": 1e300, "cy": 60}}, "cx=1e+300"),
]


@pytest.mark.anyio
@pytest.mark.parametrize(("case", "change", "message"), BAD_FRAMES, ids=[c[0] for c in BAD_FRAMES])
async def test_a_poisoning_frame_is_refused_by_the_server_and_everything_keeps_working(
    tmp_path: Path, case: str, change: dict[str, Any], message: str
) -> None:
    maps = tmp_path / "maps"
    async with Client(build_server(config(tmp_path))) as client:
        await client.call_tool("new_map", {"name": "flat"})
        await client.call_tool("observe_frame", frame_args())
        before, file_before = await counts(client), (maps / "flat.glmap").read_bytes()
        refused = await client.call_tool("observe_frame", _with(frame_args(), **change))
        assert refused.is_error, case
        assert message in refused.content[0].text
        assert await counts(client) == before
        assert (maps / "flat.glmap").read_bytes() == file_before
        hits = await client.call_tool("find_instance", {"query": "red wooden chair"})
        assert not hits.is_error and hits.structured_content["hits"]
        chair = hits.structured_content["hits"][0]["id"]
        for tool, args in [
            ("what_is_at", {"x": 0.0, "y": 0.0, "radius": 0.5}),
            ("describe_unit", {"id": chair}),
            ("map_summary", {}),
            ("export_ply", {"name": "flat"}),
        ]:
            result = await client.call_tool(tool, args)
            assert not result.is_error, (tool, result.content[0].text)
    async with Client(build_server(config(tmp_path))) as client:
        loaded = await client.call_tool("load_map", {"name": "flat"})
        assert not loaded.is_error and await counts(client) == before


@pytest.mark.anyio
async def test_the_server_refuses_a_description_or_group_count_over_its_limit(
    tmp_path: Path,
) -> None:
    async with Client(build_server(config(tmp_path))) as client:
        args = frame_args()
        args["annotations"]["objects"][0]["description"] = "x" * (MAX_DESCRIPTION_CHARS + 1)
        long = await client.call_tool("observe_frame", args)
        assert long.is_error and str(MAX_DESCRIPTION_CHARS) in long.content[0].text
        args = frame_args()
        first = args["annotations"]["objects"][0]["id"]
        args["annotations"]["groups"] = [
            {"id": g, "description": "a corner", "members": [first]} for g in range(MAX_GROUPS + 1)
        ]
        many = await client.call_tool("observe_frame", args)
        assert many.is_error and str(MAX_GROUPS) in many.content[0].text
        assert await counts(client) == (0, 0, 0)


# ---------------------------------------------------------------------- lock work


class CachingEmbedder:
    """The hashing embedder behind a text -> vector cache, counting texts not in it."""

    def __init__(self) -> None:
        self.inner = HashingEmbedder()
        self.name, self.dim, self.default_tau_s = "caching", self.inner.dim, 0.2
        self.cache: dict[str, np.ndarray] = {}
        self.misses = 0

    def embed(self, texts):  # type: ignore[no-untyped-def]
        new = [t for t in dict.fromkeys(texts) if t not in self.cache]
        self.misses += len(new)
        self.cache.update(zip(new, self.inner.embed(new), strict=True) if new else [])
        return np.stack([self.cache[t] for t in texts]) if texts else np.zeros((0, self.dim))


def test_after_embed_ahead_integrating_long_repeated_descriptions_embeds_nothing_new() -> None:
    from glmap_tools.app.inputs import embed_ahead
    from glmap_tools.bench.lock import costly_description, tiled_frame

    embedder = CachingEmbedder()
    glmap = GLMap(MapConfig(voxel_size=0.04), embedder=embedder)
    frame, ids = tiled_frame(6, 96, 72)
    rng = np.random.default_rng(0)
    # About 200 words per description: two sightings overflow the 300-word buffers.
    pools = [[f"w{k}x{i}" for i in range(80)] for k in range(6)]
    merged = 0
    for _ in range(3):
        annotation = {
            "objects": [
                {"id": k + 1, "description": costly_description(rng, pools[k], 1000)}
                for k in range(6)
            ],
            "groups": [
                {"id": 1, "description": costly_description(rng, pools[0], 1000), "members": [1, 2]}
            ],
        }
        semantics = semantics_from_annotation(ids, annotation)
        embed_ahead(embedder, semantics)
        embedder.misses = 0
        report = glmap.integrate(frame, semantics)  # the part that runs under the map's lock
        assert embedder.misses == 0
        merged += len(report.instances_merged) + len(report.regions_merged)
    assert merged >= 10  # the buffers overflowed and were merged under the lock
    # Every buffer was merged (the raw descriptions alone hold 3 x ~200 words).
    assert all(150 < len(u.text.split()) <= 300 for u in glmap.instances.values())


@pytest.mark.parametrize(
    ("call", "said"),
    [
        (lambda g: g.find_instances("a chair", k="3"), "k='3' must be a whole number in 1.."),
        (lambda g: g.find_regions("a kitchen", k=float("inf")), "k=inf must be a whole number"),
        (lambda g: g.find_instances("a chair", k=True), "k=True must be a whole number"),
        (lambda g: g.unit({}), "unit id {} is not an integer"),
        (lambda g: g.unit_details("chair"), "unit id 'chair' is not an integer"),
        (lambda g: g.regions_of_instance([1]), "unit id [1] is not an integer"),
        (lambda g: g.units_at(1e308, 0.0), "lies more than 1e+06 m from the map's origin"),
        (lambda g: g.units_at("x", 0.0), "x='x' is not a number"),
        (lambda g: g.units_at(0.0, 0.0, -(2**70)), "must be finite|must be in 0..20"),
    ],
)
def test_a_library_query_with_an_argument_of_the_wrong_kind_names_it(call: Any, said: str) -> None:
    glmap = GLMap(MapConfig(), embedder=HashingEmbedder())
    with pytest.raises(InvalidInputError) as refused:
        call(glmap)
    assert any(part in str(refused.value) for part in said.split("|")), refused.value
    assert glmap.find_instances("a chair", k=np.int64(3)) == []  # numpy integers are whole
