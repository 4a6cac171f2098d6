"""`glmap eval --ray-address local`: a Ray instance on this machine plays episodes.

Ray is the engine here, not a stand-in: a real local Ray instance (the tests' shared
`running_ray`, which `--ray-address local` uses as it is), one actor holds an in-memory MCP
session, and its results must equal those of the same seeded episodes played in this process.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from agents.runner import LLM_ENV
from glmap_tools.eval import EvalSpec
from glmap_tools.eval.run import run_eval
from glmap_tools.language.ollama_replay import ScriptedOllama
from tests import llm_scenarios as sc

KEYS = ("success", "spl", "distance_to_goal", "steps", "path_length", "collisions", "seed")


@pytest.mark.slow  # 4 episodes (and the Ray start when first)
def test_a_local_ray_instance_plays_episodes_as_the_local_workers_do(
    running_ray: object, tmp_path: Path
) -> None:
    spec = EvalSpec("objectnav", "tune", 1, 1, ("glmap", "random"), max_steps=3, embedder="hashing")
    on_ray = run_eval(spec, tmp_path / "ray", workers=1, ray_address="local", progress=False)
    assert on_ray.failures == [] and (on_ray.ran, on_ray.skipped) == (2, 0)
    assert sorted(p.parent.name for p in (tmp_path / "ray" / "episodes").glob("*/*.json")) == [
        "glmap",
        "random",
    ]
    here = run_eval(spec, tmp_path / "here", workers=0, progress=False)
    for agent in spec.agents:
        (eid,) = on_ray.records[agent]
        ray_record, here_record = on_ray.records[agent][eid], here.records[agent][eid]
        assert {k: ray_record[k] for k in KEYS} == {k: here_record[k] for k in KEYS}
    again = run_eval(spec, tmp_path / "ray", workers=1, ray_address="local", progress=False)
    assert (again.ran, again.skipped) == (0, 2)  # resuming needs no Ray start at all


@pytest.mark.slow  # 1 episode (and the Ray start when first)
def test_actors_of_a_running_ray_instance_get_the_llm_settings_of_the_driver(
    running_ray: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Ray started before the settings exist (`running_ray`), so its workers cannot inherit
    # them (as on a cluster that was already running): only what run_ray hands each actor
    # gets there.
    for var in LLM_ENV.values():
        monkeypatch.delenv(var, raising=False)
    with ScriptedOllama(sc.keyword_scores) as model:
        monkeypatch.setenv(LLM_ENV["scorer"], "llm")
        monkeypatch.setenv(LLM_ENV["model"], sc.MODEL)
        monkeypatch.setenv(LLM_ENV["host"], model.host)
        spec = EvalSpec(
            "objectnav", "tune", 1, 1, ("glmap",), max_steps=4, embedder="hashing",
            scorer="llm", llm_model=sc.MODEL,
        )  # fmt: skip
        run = run_eval(spec, tmp_path, workers=1, ray_address="local", progress=False)
    assert run.failures == [] and run.ran == 1
    assert any(path == "/api/chat" for _, path, _ in model.requests)
    (record,) = run.records["glmap"].values()
    assert "scorer_used" not in record
