"""The client's f_S (value_map's scores and priors): the scorer layer over the configured
scorer, and the tools through an in-memory MCP client (value_map, nav_step, navigate_to)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from mcp import Client

from glmap_tools.errors import InvalidInputError
from glmap_tools.nav.scorers import MAX_PRIORS, ClientScorer, ClientScores, UnitText
from glmap_tools.server import build_server
from glmap_tools.worlds.splits import load_split
from tests.test_server_fixtures import config

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
EPISODE = load_split("tune", "objectnav")[0].episode_id


class Fixed:
    """A base scorer giving every unit 0.2, with category margins of 0.1."""

    def score(self, goal, units):  # type: ignore[no-untyped-def]
        return np.full(len(units), 0.2)

    def category_margins(self, goal, units, labels=None):  # type: ignore[no-untyped-def]
        return np.full(len(units), 0.1)


class Plain:
    def score(self, goal, units):  # type: ignore[no-untyped-def]
        return np.full(len(units), 0.2)


UNITS = [
    UnitText(1, "instance", "a red wooden chair"),
    UnitText(2, "instance", "a white refrigerator"),
    UnitText(9, "region", "cooking area: a fridge and a stove, for preparing food"),
    UnitText(10, "region", "sleeping area: a bed, for sleeping"),
]


def test_client_scores_override_the_scorer_and_priors_score_regions_of_that_kind():
    client = ClientScores("a fridge", {2: 0.9}, {"cooking area": 0.7, "bed": 0.05})
    scorer = ClientScorer(Fixed(), client, match_at=0.56)
    got = scorer.score("A  Fridge", UNITS)  # the same goal, case and spacing aside
    assert got.tolist() == [0.2, 0.9, 0.7, 0.05]
    assert scorer.sources("a fridge", UNITS) == ["scorer", "client", "prior", "prior"]
    # Another goal is the configured scorer's alone.
    assert scorer.score("a sofa", UNITS).tolist() == [0.2] * 4
    assert scorer.sources("a sofa", UNITS) == ["scorer"] * 4


def test_held_priors_of_any_length_still_score_regions():
    """value_map refuses a kind over 60 characters; kinds held already (an episode record
    kept before that limit) are still matched at every step."""
    long_kind = "cooking area " + "with a stove " * 8  # 117 characters
    client = ClientScores("a fridge", {}, {long_kind: 0.7})
    got = ClientScorer(Fixed(), client, match_at=0.56).score("a fridge", UNITS)
    assert got.tolist() == [0.2, 0.2, 0.2, 0.2]  # no region holds all its words: no prior


def test_a_client_scored_instance_matches_by_its_score_not_the_vocabulary():
    client = ClientScores("fridge", {1: 0.1, 2: 0.9})
    scorer = ClientScorer(Fixed(), client, match_at=0.56)
    assert scorer.category_margins is not None
    margins = scorer.category_margins("fridge", UNITS[:2], ["chair", "fridge"])
    assert margins.tolist() == [-np.inf, np.inf]
    # A base scorer without margins keeps the plain stop threshold: no margins either.
    assert ClientScorer(Plain(), client, 0.56).category_margins is None


def test_a_fused_id_s_score_follows_its_fusion_and_the_higher_score_wins():
    client = ClientScores("fridge", {4: 0.3, 5: 0.8, 7: 0.5})
    moved = client.follow({4: 7, 5: 6, 6: 7})
    assert moved == {4: 7, 5: 7}
    assert client.units == {7: 0.8}


def test_a_goal_match_reads_the_client_scores_through_the_policy_s_detector():
    from glmap_tools.nav.config import NavConfig
    from glmap_tools.nav.perceive import find_goal_match

    class Grid:
        def cells_of_unit(self, uid):  # type: ignore[no-untyped-def]
            return frozenset({(uid, 0)})

    class Map:
        grid = Grid()
        instances: dict = {}  # no Gaussians: a match's footprint is its grid cells

    units = [UnitText(1, "instance", "a chair", observations=3, label="chair")]
    units.append(UnitText(2, "instance", "a fridge", observations=3, label="fridge"))
    config = NavConfig.for_task("objectnav")
    for said, want in (({1: 0.0, 2: 0.9}, 2), ({1: 0.9, 2: 0.1}, 1), ({1: 0.3}, None)):
        scorer = ClientScorer(Fixed(), ClientScores("fridge", said), config.stop_threshold)
        scores = scorer.score("fridge", units)
        match = find_goal_match(Map(), units, scores, set(), config, scorer, "fridge")  # type: ignore[arg-type]
        assert (match.unit_id if match else None) == want, said


pytestmark = pytest.mark.anyio


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def ok(result) -> dict:  # type: ignore[no-untyped-def, type-arg]
    assert not result.is_error, result.content[0].text
    return json.loads(result.content[0].text)


def error(result) -> str:  # type: ignore[no-untyped-def]
    assert result.is_error
    return str(result.content[0].text)


async def test_client_scores_steer_value_map_nav_step_and_navigate_to_until_sim_reset(tmp_path):
    server = build_server(config(tmp_path, sim_size=(160, 120)))
    async with Client(server) as client:
        before = await client.call_tool("value_map", {"goal": "a bed", "scores": {"1": 0.5}})
        ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        ok(await client.call_tool("look_around", {}))
        plain = ok(await client.call_tool("value_map", {}))
        units = (await client.call_tool("find_region", {"query": "room"})).structured_content
        region = units["hits"][0]
        mine = min(region["instance_ids"])
        args = {"scores": {str(mine): 1.0}, "priors": {"area": 0.4}}
        steered = ok(await client.call_tool("value_map", args))
        again = ok(await client.call_tool("value_map", {}))
        other_goal = ok(await client.call_tool("value_map", {"goal": "a toaster"}))
        wrong_goal = await client.call_tool("value_map", {"goal": "a toaster", **args})
        walk = ok(await client.call_tool("navigate_to", {"unit_id": mine, "max_steps": 1}))
        step = ok(await client.call_tool("nav_step", {"actions": 1}))
        unknown = await client.call_tool("value_map", {"scores": {"99999": 0.5}})
        too_big = await client.call_tool("value_map", {"scores": {str(mine): 1.5}})
        empty_kind = await client.call_tool("value_map", {"priors": {" ": 0.5}})
        kinds = {f"kind {k}": 0.5 for k in range(MAX_PRIORS)}  # with "area": one too many
        too_many = await client.call_tool("value_map", {"priors": kinds})
        too_long = await client.call_tool("value_map", {"priors": {"room " * 20: 0.5}})
        kept = ok(await client.call_tool("value_map", {}))
        full = ok(await client.call_tool("value_map", {"priors": kinds, "clear": True}))
        cleared = ok(await client.call_tool("value_map", {"clear": True}))
        ok(await client.call_tool("value_map", args))
        ok(await client.call_tool("sim_reset", {"episode": EPISODE}))
        fresh = ok(await client.call_tool("value_map", {}))
    assert "sim_reset" in error(before)
    assert all(row[3] == "scorer" for row in plain["top_units"]) and "client" not in plain
    for shown in (plain, steered, other_goal, fresh):  # never empty without saying why
        assert shown["evidence"] in ("units", "region hint", "none")
        assert (shown["top_cells"] == []) == (shown["evidence"] == "none"), shown
    assert steered["evidence"] == "units"  # the client's 1.0 passes the gate
    held = steered["client"]
    assert held["scores"] == [[mine, "instance", 1.0]]
    assert held["priors"][0][:2] == ["area", 0.4] and region["id"] in held["priors"][0][2]
    top = steered["top_units"][0]
    assert top[0] == mine and top[2] == 1.0 and top[3] == "client"
    assert any(row[3] == "prior" for row in steered["top_units"])
    assert again["client"] == held and again["top_units"] == steered["top_units"]
    assert all(row[3] == "scorer" for row in other_goal["top_units"])
    assert "episode's goal" in error(wrong_goal)
    assert walk["goal_score"] == 1.0 and walk["score_by"] == "client"
    assert step["client_scores"] == {"units": 1, "priors": 1}
    assert "99999" in error(unknown) and "Closest id" in error(unknown)
    assert "1.5" in error(too_big) and "[0, 1]" in error(too_big)
    assert "empty" in error(empty_kind)
    assert f"{MAX_PRIORS + 1} region kinds, more than {MAX_PRIORS}" in error(too_many)
    assert "100 characters, more than 60" in error(too_long)
    assert len(full["client"]["priors"]) == MAX_PRIORS
    assert kept["client"] == held  # the refused calls changed nothing
    assert "client" not in cleared and all(r[3] == "scorer" for r in cleared["top_units"])
    assert "client" not in fresh and all(row[3] == "scorer" for row in fresh["top_units"])


def test_a_bad_score_names_the_value_and_the_fix():
    from glmap_tools.nav.scorers import check_unit_score

    for bad in (-0.1, 1.01, float("nan"), "high", True):
        with pytest.raises(InvalidInputError, match=r"not in \[0, 1\]; give how likely"):
            check_unit_score(bad, "unit 3")


def test_a_score_for_a_fused_id_is_kept_on_the_unit_it_became():
    from glmap_tools.app.client_scores import check_client_scores
    from glmap_tools.errors import UnknownIdError

    class Map:
        instances = {7: object()}
        regions: dict[int, object] = {}
        fused_into = {3: 5, 5: 7}

        def unit(self, uid):  # type: ignore[no-untyped-def]
            if uid not in self.instances:
                raise UnknownIdError(f"unit id {uid} does not exist. Closest id: 7.")

    live, kinds, followed = check_client_scores(Map(), {3: 0.6, 7: 0.2}, {"Dining  Area": 1})
    assert live == {7: 0.6} and followed == {3: 7} and kinds == {"dining area": 1.0}
    with pytest.raises(UnknownIdError, match="Closest id: 7"):
        check_client_scores(Map(), {8: 0.5}, {})


async def test_the_client_scores_go_on_in_the_next_server_of_a_kept_episode(tmp_path):
    import sqlite3

    start = {"episode": EPISODE, "size": "160x120"}
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
        ok(await client.call_tool("sim_reset", start))
        said = ok(await client.call_tool("value_map", {"priors": {"kitchen": 0.9}}))
    async with Client(build_server(config(tmp_path, map_name="ep"))) as client:
        again = ok(await client.call_tool("value_map", {}))
    with sqlite3.connect(tmp_path / "maps" / "ep.glmap") as conn:
        (text,) = conn.execute("SELECT value FROM meta WHERE key = 'extra.sim_episode'").fetchone()
    assert json.loads(text)["client_scores"] == {"units": [], "priors": [["kitchen", 0.9]]}
    assert again["client"] == said["client"]


async def test_looking_at_the_value_map_leaves_the_policy_s_path_as_it_was(tmp_path):
    """value_map decides on a copy of the episode's policy memory: a client that looks at
    the value map between nav_step calls walks the same path as one that never looks."""
    paths = []
    for look in (False, True):
        server = build_server(config(tmp_path / str(look), sim_size=(160, 120)))
        async with Client(server) as client:
            ok(await client.call_tool("sim_reset", {"episode": EPISODE, "seed": 3}))
            path = []
            for _ in range(18):
                if look:
                    ok(await client.call_tool("value_map", {}))
                step = ok(await client.call_tool("nav_step", {"actions": 1}))
                path.append((step["steps"], step["position"], step["heading_deg"]))
        paths.append(path)
    assert paths[0] == paths[1]
