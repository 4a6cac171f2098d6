"""`glmap eval`: 2 scenes x 3 episodes x every agent on worker processes, resuming, bad input.

Episodes are real: each worker process holds an in-memory MCP session on `build_server` and
plays benchmark episodes (tune split, 320x240, hashing embedder) through `agents.runner`.
The step limit is cut to 2 so the whole file stays fast; the harness is what is under test.
"""

from __future__ import annotations

import json
import socket
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from glmap_tools import cli
from glmap_tools.errors import InvalidInputError
from glmap_tools.eval import EvalSpec, episode_seed, select_episodes
from glmap_tools.eval.ray_engine import CONNECT_TIMEOUT_S, RayUnavailableError, check_address
from glmap_tools.eval.run import EvalRun, run_eval

MAX_STEPS = 2
# Every agent that needs no model (llm-tools needs an Ollama model and stays out of CI).
AGENTS = ("glmap", "glmap-instance", "glmap-region", "egocentric", "frontier", "random")


def spec(**kw: object) -> EvalSpec:
    base: dict[str, object] = {
        "task": "objectnav",
        "split": "tune",
        "scenes": 2,
        "episodes_per_scene": 3,
        "agents": AGENTS,
        "max_steps": MAX_STEPS,
        "embedder": "hashing",
    }
    return EvalSpec(**{**base, **kw})  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> EvalRun:
    out = tmp_path_factory.mktemp("eval") / "objectnav"
    return run_eval(spec(), out, workers=2, progress=False)


@pytest.mark.slow  # shares the 36-episode run: 42-51 s at load 10-15 on 2 cores
def test_two_scenes_by_three_episodes_run_with_every_agent_on_two_workers(
    finished: EvalRun,
) -> None:
    assert finished.failures == [] and finished.ran == 2 * 3 * len(AGENTS)
    files = sorted((finished.out / "episodes").glob("*/*.json"))
    assert len(files) == 36
    scenes = set()
    for agent in AGENTS:
        records = finished.records[agent]
        assert len(records) == 6
        for eid, r in records.items():
            assert r["agent"] == agent and r["episode_id"] == eid
            assert r["seed"] == episode_seed(0, eid)  # the same seed for every agent
            assert 1 <= r["steps"] <= MAX_STEPS and r["tool_calls"] >= 2
            assert r["config"]["max_steps"] == MAX_STEPS
            scenes.add(r["scene"])
    assert scenes == {"s00", "s01"}
    stored = json.loads(files[0].read_text())
    assert {"success", "spl", "distance_to_goal", "steps", "tool_calls", "wall_s"} <= set(stored)


@pytest.mark.slow  # shares the 36-episode run: 42-51 s at load 10-15 on 2 cores
def test_the_summary_has_a_row_per_agent_and_paired_rows_against_the_first(
    finished: EvalRun,
) -> None:
    text = (finished.out / "summary.md").read_text()
    for agent in AGENTS:
        assert f"\n| {agent} | 6 | " in text
    for other in AGENTS[1:]:
        assert f"\n| glmap − {other} | 6 | " in text
    assert "2000 resamples" in text
    data = json.loads((finished.out / "summary.json").read_text())
    assert data["ran"] == 36 and data["bootstrap"]["method"] == "percentile"
    assert data["agents"]["random"]["steps"]["mean"] == MAX_STEPS  # random never stops


@pytest.mark.slow  # shares the 36-episode run: 42-51 s at load 10-15 on 2 cores
def test_a_rerun_skips_finished_episodes_and_plays_only_missing_or_stale_ones(
    finished: EvalRun,
) -> None:
    again = run_eval(spec(), finished.out, workers=2, progress=False)
    assert (again.ran, again.skipped) == (0, 36)
    assert again.records == finished.records
    episodes = finished.out / "episodes"
    gone = episodes / "frontier" / "tune__objectnav__s01-002.json"
    stale = episodes / "glmap" / "tune__objectnav__s00-001.json"
    before = {p: json.loads(p.read_text()) for p in (gone, stale)}
    gone.unlink()
    table_only = run_eval(spec(), finished.out, play=False, progress=False)
    assert (table_only.ran, len(table_only.records["frontier"])) == (0, 5)
    assert "Finished: 35 of 36 (agent, episode) pairs." in (finished.out / "summary.md").read_text()
    same = run_eval(spec(), finished.out, play=False, complete_only=True, progress=False)
    assert {len(r) for r in same.records.values()} == {5}  # every row on the same 5 episodes
    assert "(only episodes every agent finished)" in (finished.out / "summary.md").read_text()
    # A result of an episode whose benchmark files changed since is not silently reused.
    stale.write_text(json.dumps({**before[stale], "episode_key": "0" * 16}))
    with pytest.raises(InvalidInputError, match="played on other benchmark files"):
        run_eval(spec(), finished.out, workers=0, progress=False)
    third = run_eval(spec(), finished.out, workers=0, mix_configs=True, progress=False)
    assert (third.ran, third.skipped) == (2, 34)
    for path, old in before.items():
        replay = json.loads(path.read_text())
        for key in ("success", "spl", "distance_to_goal", "steps", "path_length", "episode_key"):
            assert replay[key] == old[key]  # a seeded episode replays identically


@pytest.mark.slow  # shares the 36-episode run: 42-51 s at load 10-15 on 2 cores
def test_a_changed_setting_is_refused_unless_mixing_is_asked_for(finished: EvalRun) -> None:
    config = (finished.out / "eval.json").read_bytes()
    with pytest.raises(InvalidInputError, match=r"max_steps: 2 -> 3.*--mix-configs"):
        run_eval(spec(max_steps=3), finished.out, workers=0, progress=False)
    assert (finished.out / "eval.json").read_bytes() == config
    mixed = run_eval(
        spec(max_steps=3, episodes_per_scene=1), finished.out, mix_configs=True, progress=False
    )
    assert mixed.mixed and mixed.ran == 0
    assert "mixes results run with different settings" in (finished.out / "summary.md").read_text()


RECORD = {
    "episode_id": "tune/objectnav/s00-000",
    "agent": "glmap",
    "success": True,
    "spl": 0.5,
    "distance_to_goal": None,  # a non-finite float is stored as null
    "steps": 40,
    "path_length": 6.0,
    "collisions": 0,
    "tool_calls": 42,
    "wall_s": 3.0,
    "seed": 7,
    "outcome": "success",
}


@pytest.mark.parametrize(
    "edit",
    [
        {"spl": {"a": 1}},
        {"success": "yes"},
        {"steps": [1]},
        {"steps": True},
        {"outcome": {"a": 1}},
        {"config": 3},
        {"prompts": []},
        {"tool_calls": None},
    ],
)
def test_a_stored_record_whose_fields_are_not_an_episodes_is_played_again(
    tmp_path: Path, edit: dict[str, object]
) -> None:
    from glmap_tools.eval.results import ResultsDir, record_problem

    results = ResultsDir(tmp_path / "out", {"task": "objectnav"})
    results.save(RECORD)
    assert results.load("glmap", RECORD["episode_id"])["spl"] == 0.5  # type: ignore[index]
    path = results.episode_path("glmap", str(RECORD["episode_id"]))
    path.write_text(json.dumps({**json.loads(path.read_text()), **edit}))
    assert results.load("glmap", str(RECORD["episode_id"])) is None  # as an unreadable file
    (name,) = edit
    assert str(record_problem({**RECORD, **edit})).startswith(f"{name} = ")


@pytest.mark.parametrize("stored", [{"config": []}, {"history": 5}, {"history": [1, 2]}])
def test_an_eval_json_of_the_wrong_shape_is_refused_naming_the_file(
    tmp_path: Path, stored: dict[str, object]
) -> None:
    from glmap_tools.eval.results import ResultsDir

    out = tmp_path / "out"
    ResultsDir(out, {"task": "objectnav"})
    path = out / "eval.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), **stored}))
    before = path.read_bytes()
    with pytest.raises(InvalidInputError, match=f"{path} has a 'config' that is not an object"):
        ResultsDir(out, {"task": "objectnav"})
    assert path.read_bytes() == before


def test_an_unknown_agent_name_suggests_the_closest_one(tmp_path: Path) -> None:
    with pytest.raises(InvalidInputError, match="unknown agent 'glmapp'. Did you mean 'glmap'"):
        run_eval(spec(agents=("glmapp",)), tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_the_cli_reports_bad_input_as_an_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["eval", "objectnav", "--split", "tune", "--out", str(tmp_path / "o")]
    assert cli.main([*argv, "--agents", "glmap,fronteir"]) == 1
    assert "Did you mean 'frontier'" in capsys.readouterr().err
    assert cli.main([*argv, "--scenes", "99"]) == 1
    assert "the tune split has 4 objectnav scenes; use --scenes 4 or fewer" in (
        capsys.readouterr().err
    )
    assert cli.main([*argv, "--scenes", "1", "--episodes-per-scene", "9999"]) == 1
    assert "--episodes-per-scene 9999" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("address", ["127.0.0.1:1", "ray://127.0.0.1:1"])
def test_a_ray_address_that_does_not_answer_fails_within_ten_seconds(
    address: str, tmp_path: Path
) -> None:
    start = time.perf_counter()
    with pytest.raises(RayUnavailableError, match="does not answer"):
        run_eval(spec(), tmp_path / "out", ray_address=address, progress=False)
    assert time.perf_counter() - start < 10.0
    assert not (tmp_path / "out").exists()


def test_a_silent_ray_address_times_out_instead_of_hanging() -> None:
    assert CONNECT_TIMEOUT_S < 10.0
    with socket.socket() as silent:  # accepts connections (kernel backlog), never answers
        silent.bind(("127.0.0.1", 0))
        silent.listen(4)
        start = time.perf_counter()
        with pytest.raises(RayUnavailableError, match="no answer; waited at most 1 s"):
            check_address(f"127.0.0.1:{silent.getsockname()[1]}", timeout_s=1.0)
        assert time.perf_counter() - start < 3.0


def test_a_grpc_server_that_is_not_ray_is_told_apart() -> None:
    import grpc

    server = grpc.server(ThreadPoolExecutor(1))
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        for address in (f"127.0.0.1:{port}", f"ray://127.0.0.1:{port}"):
            with pytest.raises(RayUnavailableError, match="not a Ray server"):
                check_address(address)
    finally:
        server.stop(0)


def test_a_malformed_ray_address_says_what_forms_work() -> None:
    with pytest.raises(InvalidInputError, match="HOST:PORT or ray://HOST:PORT"):
        check_address("my-cluster")


def test_the_selection_is_the_first_scenes_and_their_first_episodes() -> None:
    from glmap_tools.worlds.splits import load_split

    every = load_split("tune", "instnav")
    scenes = sorted({be.scene for be in every})[:2]
    expected = [[be.episode_id for be in every if be.scene == s][:3] for s in scenes]
    chosen = [be.episode_id for be in select_episodes("instnav", "tune", 2, 3)]
    assert chosen == expected[0] + expected[1]
    assert chosen == [be.episode_id for be in select_episodes("instnav", "tune", 2, 3)]


@pytest.mark.parametrize("resamples", [0, 100_000_000])  # 1e8 ran for minutes after the play
def test_bootstrap_resamples_out_of_range_are_refused_before_any_episode(tmp_path, resamples):
    out = tmp_path / "run"
    with pytest.raises(InvalidInputError, match=f"resamples={resamples} must be 1 to 100,000"):
        run_eval(spec(scenes=1, episodes_per_scene=1), out, workers=0, resamples=resamples)
    assert not out.exists()
