"""LLM-backed parts replayed from recordings through the real `ollama` client code.

Set GLMAP_OLLAMA_RECORD=<live Ollama URL> to record the re-recordable cassettes instead of
replaying them (exact-value checks are skipped then: a real model answers differently).
"""

import json
import os
import re
import socket

import numpy as np
import pytest

from glmap_tools.errors import LLMError, LLMOutputError, LLMUnavailableError, ReplayMissError
from glmap_tools.language.llm import OllamaClient, chat_structured, extract_json
from glmap_tools.language.llm_scorer import LLMScorer, UnitScores
from glmap_tools.language.ollama_replay import (
    RECORD_ENV,
    Cassette,
    OllamaReplayServer,
    ScriptedOllama,
    chat_reply,
)
from glmap_tools.language.transcript import Transcript
from glmap_tools.nav.scorers import UnitText
from tests import llm_scenarios as sc

RECORDING = bool(os.environ.get(RECORD_ENV))


def replay(name: str, **kw) -> OllamaReplayServer:
    return OllamaReplayServer(
        sc.CASSETTES / name, record_from_env=True, record_command=sc.record_command(name), **kw
    )


def test_every_cassette_says_where_its_replies_came_from():
    for path in sorted(sc.CASSETTES.glob("*.jsonl")):
        header = Cassette.load(path).header
        assert header["source"].startswith(("recorded from", "written by hand")), path
        assert header["record"], path


def test_llm_scorer_replays_its_recorded_probabilities_and_caches_them():
    with replay("nav_scores.jsonl") as server:
        scorer = LLMScorer(sc.client(server.host))
        scores = scorer.score("tv", sc.NAV_UNITS)
        assert scorer.calls == 2  # one batch of instances, one of regions
        again = scorer.score("tv", sc.NAV_UNITS)
        assert scorer.calls == 2 and np.array_equal(scores, again)
    assert scores.shape == (5,) and np.all((scores >= 0) & (scores <= 1))
    # The television beats the bathtub, the living room beats the bathroom.
    assert scores[0] > scores[1] and scores[3] > scores[4]
    if not RECORDING:
        np.testing.assert_allclose(scores, [0.92, 0.05, 0.92, 0.92, 0.05])


def test_the_llm_text_merger_rewrites_a_map_buffer_past_300_words():
    with replay("map_text_merge.jsonl") as server:
        glmap = sc.map_text_merge(server.host)
    (unit,) = glmap.instances.values()
    assert len(unit.text.split()) <= glmap.config.max_text_words
    assert glmap.text_merger.calls >= 1
    if not RECORDING:
        assert unit.text.startswith(sc.CHAIR_BASE + "; details detail0x0")


@pytest.mark.skipif(RECORDING, reason="hand-written fault replies cannot be recorded")
def test_json_in_prose_missing_an_id_is_retried_and_the_fenced_answer_accepted():
    with Transcript() as transcript, replay("faults.jsonl") as server:
        scorer = LLMScorer(sc.client(server.host, transcript=transcript))
        scores = scorer.score("tv", sc.NAV_UNITS[:2])
    np.testing.assert_allclose(scores, [0.9, 0.02])
    requests = [e for e in transcript.events if e["kind"] == "llm_request"]
    assert len(requests) == 2
    assert "missing [2]" in requests[1]["messages"][-1]["content"]
    assert requests[0]["prompt"].startswith("unit_value_instance@")


@pytest.mark.skipif(RECORDING, reason="hand-written fault replies cannot be recorded")
def test_a_probability_outside_0_1_after_a_retry_is_a_clear_error():
    with replay("faults.jsonl") as server:
        scorer = LLMScorer(sc.client(server.host))
        with pytest.raises(LLMOutputError, match=r"less than or equal to 1.*--prompts"):
            scorer.score("bathtub", sc.NAV_UNITS[:2])
    assert scorer.cache == {}


@pytest.mark.skipif(RECORDING, reason="replay only")
def test_a_request_missing_from_the_recording_names_the_closest_and_how_to_re_record():
    with replay("nav_scores.jsonl") as server:
        scorer = LLMScorer(sc.client(server.host))
        with pytest.raises(ReplayMissError) as err:
            scorer.score("a television set", sc.NAV_UNITS)
    message = str(err.value)
    assert "closest recorded request: #1" in message
    assert "a television set" in message and "similarity" in message
    assert "GLMAP_OLLAMA_RECORD=http://127.0.0.1:11434" in message
    assert "tests/test_llm_replay.py -k nav_scores" in message


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (lambda lines: lines[1].pop("response"), "line 2 is not a recorded exchange"),
        (lambda lines: lines[1].update(key=3), "line 2 is not a recorded exchange"),
        (lambda lines: lines[1]["response"].update(status="x"), "line 2 is not a recorded"),
        (lambda lines: lines[0].update(version="x"), "has cassette version 'x'; this reads 1..1"),
        (lambda lines: lines.__setitem__(0, [1]), "is not a glmap-ollama-cassette file"),
    ],
    ids=["no response", "key a number", "status text", "version text", "header a list"],
)
def test_a_malformed_cassette_is_refused_naming_the_line(tmp_path, change, said):
    # before: KeyError / TypeError / ValueError at load, or in the server's handler thread
    from glmap_tools.errors import StoreError

    lines = [json.loads(x) for x in (sc.CASSETTES / "nav_scores.jsonl").read_text().splitlines()]
    change(lines)
    path = tmp_path / "c.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    with pytest.raises(StoreError, match=re.escape(said)):
        Cassette.load(path)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_ollama_says_how_to_start_it_after_retrying():
    client = OllamaClient(
        sc.MODEL, host=f"http://127.0.0.1:{_free_port()}", retries=1, backoff=0.01
    )
    with Transcript() as transcript:
        client.transcript = transcript
        with pytest.raises(LLMUnavailableError, match="ollama serve"):
            client.chat([{"role": "user", "content": "hi"}])
    assert transcript.events[-1]["kind"] == "error"


def test_a_model_that_is_not_pulled_says_run_ollama_pull():
    def not_found(method, path, body):
        return 404, {"error": f'model "{body["model"]}" not found, try pulling it first'}

    with ScriptedOllama(not_found) as server:
        client = OllamaClient("gemma3:27b", host=server.host, retries=2, backoff=0.01)
        with pytest.raises(LLMUnavailableError, match="run `ollama pull gemma3:27b`"):
            client.chat([{"role": "user", "content": "hi"}])
        assert len(server.requests) == 1  # no retry can help


def test_a_slow_model_times_out_with_a_clear_error_after_the_retries():
    with ScriptedOllama(lambda m, p, b: (200, chat_reply(sc.MODEL, "late")), delay=0.5) as server:
        client = OllamaClient(sc.MODEL, host=server.host, timeout=0.1, retries=1, backoff=0.01)
        with pytest.raises(LLMError, match="no answer within 0.1 s"):
            client.chat([{"role": "user", "content": "hi"}])
        assert len(server.requests) == 2


def test_a_5xx_is_retried_and_then_succeeds():
    answers = iter([(503, {"error": "loading model"}), (200, chat_reply(sc.MODEL, "ok"))])
    with ScriptedOllama(lambda m, p, b: next(answers)) as server:
        client = OllamaClient(sc.MODEL, host=server.host, retries=2, backoff=0.01)
        assert client.chat([{"role": "user", "content": "hi"}]).content == "ok"


def test_tool_calls_come_back_as_names_and_arguments():
    reply = chat_reply(sc.MODEL, "", [("find_instance", {"text": "sofa", "k": 3})])
    with ScriptedOllama(lambda m, p, b: (200, reply)) as server:
        client = OllamaClient(sc.MODEL, host=server.host)
        tools = [{"type": "function", "function": {"name": "find_instance", "parameters": {}}}]
        out = client.chat([{"role": "user", "content": "find the sofa"}], tools=tools)
    assert [(c.name, c.arguments) for c in out.tool_calls] == [
        ("find_instance", {"text": "sofa", "k": 3})
    ]
    body = server.requests[0][2]
    assert body["tools"][0]["function"]["name"] == "find_instance"


def test_images_reach_a_vision_model_and_are_dropped_for_a_text_model():
    seen = []

    def record(method, path, body):
        seen.append(body["messages"][0].get("images"))
        return 200, chat_reply(sc.MODEL, "a chair")

    png = b"\x89PNG\r\n\x1a\n" + bytes(32)
    with ScriptedOllama(record) as server:
        for vision in (True, False):
            client = OllamaClient(sc.MODEL, host=server.host, vision=vision)
            client.chat([{"role": "user", "content": "what is this?", "images": [png]}])
    assert seen[0] and len(seen[0]) == 1 and seen[1] is None


@pytest.mark.parametrize(
    "text",
    [
        '{"scores": []}',
        '```json\n{"scores": []}\n```',
        'Here you go: {"scores": []} -- done',
        '<think>{ not json }</think>\n{"scores": []}',
    ],
)
def test_json_is_found_bare_in_fences_and_in_prose(text):
    assert extract_json(text) == {"scores": []}


def test_a_reply_without_json_is_an_output_error_quoting_it():
    with pytest.raises(LLMOutputError, match="no JSON"):
        extract_json("I cannot help with that.")


@pytest.mark.parametrize("text", ["[" * 100_000, '{"a": ' * 50_000, "```json\n" + "[" * 5000])
def test_a_reply_stuck_repeating_brackets_is_an_output_error(text):
    with pytest.raises(LLMOutputError, match="nests brackets deeper than JSON is read"):
        extract_json(text)
    assert extract_json('Scores: {"scores": []} ' + "[" * 5000) == {"scores": []}


def test_structured_output_sends_the_json_schema_as_format():
    with ScriptedOllama(lambda m, p, b: (200, chat_reply(sc.MODEL, '{"scores": []}'))) as server:
        value, _ = chat_structured(
            sc.client(server.host), [{"role": "user", "content": "x"}], UnitScores
        )
    assert value.scores == []
    assert server.requests[0][2]["format"]["required"] == ["scores"]
    assert json.dumps(server.requests[0][2]["format"])  # plain JSON schema


def test_an_mllm_answers_a_situated_question_from_the_captioned_views():
    with replay("sqa_mllm.jsonl") as server:
        out = sc.sqa_mllm(server.host)
    assert out.source == "mllm" and 0.0 <= out.confidence <= 1.0
    assert out.located["situation"]["facing_text"] == "the blue chair"
    if not RECORDING:
        assert out.answer == "chair"
    # The request carried one image (the views sheet) and the direction annotations.
    request = Cassette.load(sc.CASSETTES / "sqa_mllm.jsonl").exchanges[0]["request"]["body"]
    (image,) = request["messages"][0]["images"]
    assert image.startswith("sha256:")
    assert "front (top left), left (top right)" in request["messages"][0]["content"]


def test_sqa_mllm_both_sends_the_views_then_the_topdown_crop_with_ids():
    with replay("sqa_mllm_both.jsonl") as server:
        out = sc.sqa_mllm(server.host, views="both")
    if not RECORDING:
        assert out.answer == "chair"
    request = Cassette.load(sc.CASSETTES / "sqa_mllm_both.jsonl").exchanges[0]["request"]["body"]
    message = request["messages"][0]
    assert len(message["images"]) == 2  # the views sheet, then the crop
    assert "then a top-down map crop" in message["content"]
    assert re.search(r"front: chair \([\d.]+ m, id \d+\)", message["content"])


def test_a_tool_agent_episode_replays_to_the_same_tool_results_step_by_step(tmp_path):
    """The replay matches every model request exactly, and each request carries every tool
    result so far, so a different tool result anywhere fails with a miss."""
    with replay("agent_episode.jsonl") as server:
        result = sc.agent_episode(server.host, tmp_path)
    trace = [json.loads(line) for line in (tmp_path / "episode" / "trace.jsonl").open()]
    events = [json.loads(line) for line in (tmp_path / "episode" / "transcript.jsonl").open()]
    assert [t["tool"] for t in trace][0] == "sim_reset"
    assert sum(e["kind"] == "llm_request" for e in events) == result["turns"]
    assert all(
        e.get("prompt", "").startswith("tool_agent_system@")
        for e in events
        if e["kind"] == "llm_request"
    )
    if not RECORDING:
        golden = json.loads((sc.CASSETTES / "agent_episode.result.json").read_text())
        assert {k: v for k, v in result.items() if k != "wall_s"} == golden


def test_the_llm_tools_agent_runs_through_the_runner_and_survives_an_unknown_tool(
    tmp_path, monkeypatch
):
    """A scripted stand-in asks for a tool that does not exist, then stops: the agent tells
    it so, the episode ends, and the result carries turns and the prompt's hash."""
    import asyncio

    from agents.runner import LLM_ENV, open_session, run_episode
    from glmap_tools.map import MapConfig
    from glmap_tools.server import ServerConfig

    def model(method, path, body):
        turn = sum(m["role"] == "assistant" for m in body["messages"])
        call = ("teleport", {"x": 1}) if turn == 0 else ("sim_step", {"action": "stop"})
        return 200, chat_reply(body["model"], "", [call])

    async def play():
        config = ServerConfig(
            maps_dir=tmp_path / "maps",
            embedder="hashing",
            map_config=MapConfig(voxel_size=0.04),
            warm_up=False,
        )
        async with open_session(config) as session:
            return await run_episode(
                session, sc.AGENT_EPISODE, "llm-tools", seed=0, out_dir=tmp_path / "ep"
            )

    with ScriptedOllama(model) as server:
        monkeypatch.setenv(LLM_ENV["host"], server.host)
        monkeypatch.setenv(LLM_ENV["model"], "qwen3:0.6b")
        result = asyncio.run(play())
        second = server.requests[1][2]["messages"]
    assert result.agent == "llm-tools" and result.turns == 2 and not result.success
    assert result.tool_calls == 2  # sim_reset and the stop; the unknown tool never ran
    assert result.prompts["tool_agent_system"].startswith("tool_agent_system@")
    assert "there is no tool 'teleport'" in second[-1]["content"]
    events = [json.loads(line) for line in (tmp_path / "ep" / "transcript.jsonl").open()]
    assert [e["kind"] for e in events].count("llm_request") == 2


def test_llm_scorer_scores_each_distinct_text_once_even_when_the_ids_collide() -> None:
    """A frame's objects (the egocentric frame score) all carry id -1: each text still gets
    its own score, named by its place in the batch."""
    units = [
        UnitText(-1, "instance", "a black flat-screen television"),
        UnitText(-1, "instance", "a white bathtub"),
        UnitText(-1, "instance", "a black flat-screen television"),
    ]
    with ScriptedOllama(sc.keyword_scores) as server:
        scorer = LLMScorer(sc.client(server.host))
        scores = scorer.score("tv", units)
    assert scores.tolist() == [0.92, 0.05, 0.92]
    assert scorer.calls == 1
    prompt = server.requests[-1][2]["messages"][0]["content"]
    assert "1: a black flat-screen television\n2: a white bathtub" in prompt
