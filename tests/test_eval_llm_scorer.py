"""`glmap eval --scorer llm`: the workers' servers score units with the model (a scripted
stand-in on loopback here), and the folder records the setting."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.runner import LLM_ENV
from glmap_tools import cli
from glmap_tools.eval import EvalSpec
from glmap_tools.eval.run import run_eval
from glmap_tools.eval.workers import server_llm_settings
from glmap_tools.language.backends import LLMSettings
from glmap_tools.language.ollama_replay import ScriptedOllama
from tests import llm_scenarios as sc


@pytest.fixture
def clean_llm_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """The CLI exports LLM_ENV for its workers; monkeypatch restores the shell's values."""
    for var in LLM_ENV.values():
        monkeypatch.delenv(var, raising=False)


def test_the_worker_server_takes_the_llm_scorer_from_the_environment(
    clean_llm_env: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    assert server_llm_settings() == LLMSettings()
    monkeypatch.setenv(LLM_ENV["scorer"], "embedding")
    monkeypatch.setenv(LLM_ENV["model"], "some-model")
    assert server_llm_settings() == LLMSettings()  # the model only matters to the llm parts
    monkeypatch.setenv(LLM_ENV["scorer"], "llm")
    monkeypatch.setenv(LLM_ENV["host"], "http://127.0.0.1:9")
    monkeypatch.setenv(LLM_ENV["prompts"], str(tmp_path))
    assert server_llm_settings() == LLMSettings(
        scorer="llm", model="some-model", host="http://127.0.0.1:9", prompts=tmp_path
    )


def test_eval_with_the_llm_scorer_asks_the_model_and_a_rerun_without_it_is_refused(
    clean_llm_env: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = [
        "eval", "objectnav", "--split", "tune", "--scenes", "1", "--episodes-per-scene", "1",
        "--agents", "glmap", "--workers", "0", "--max-steps", "16", "--embedder", "hashing",
        "--no-progress", "--out", str(out),
    ]  # fmt: skip
    with ScriptedOllama(sc.keyword_scores) as model:
        llm = ["--scorer", "llm", "--model", sc.MODEL, "--ollama-host", model.host]
        assert cli.main([*argv, *llm]) == 0
    chats = [body for _, path, body in model.requests if path == "/api/chat"]
    assert chats and {body["model"] for body in chats} == {sc.MODEL}
    assert all('for: "' in body["messages"][0]["content"] for body in chats)  # f_S prompts
    (record_file,) = (out / "episodes" / "glmap").glob("*.json")
    config = json.loads(record_file.read_text())["config"]
    assert config["scorer"] == "llm" and config["llm_model"] == sc.MODEL
    assert "scorer llm (qwen3:8b)" in (out / "summary.md").read_text()
    capsys.readouterr()

    assert cli.main(argv) == 1  # the offline scorer is another setting: not mixed silently
    assert "scorer" in capsys.readouterr().err
    assert [p.name for p in (out / "episodes" / "glmap").glob("*.json")] == [record_file.name]


def test_a_worker_that_scored_with_another_f_s_fails_its_episode_instead_of_mislabelling_it(
    clean_llm_env: None, tmp_path: Path
) -> None:
    # The spec asks for the LLM scorer but nothing told the worker (GLMAP_SCORER unset).
    spec = EvalSpec(
        "objectnav", "tune", 1, 1, ("glmap",), max_steps=2, embedder="hashing",
        scorer="llm", llm_model=sc.MODEL,
    )  # fmt: skip
    run = run_eval(spec, tmp_path, workers=0, progress=False)
    assert run.ran == 0 and len(run.failures) == 1
    assert "scored with f_S 'embedding', the run asks for 'llm'" in (run.failures[0].error or "")
    assert not list((tmp_path / "episodes").glob("*/*.json"))
