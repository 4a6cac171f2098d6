"""geometric+mllm: a vision model names the segments, replayed through the real ollama client."""

from __future__ import annotations

import json
import os

import pytest

from glmap_tools import synthetic as scenes
from glmap_tools.errors import LLMOutputError
from glmap_tools.language.llm import OllamaClient
from glmap_tools.language.ollama_replay import (
    RECORD_ENV,
    OllamaReplayServer,
    ScriptedOllama,
    chat_reply,
)
from glmap_tools.language.transcript import Transcript
from glmap_tools.perception.mllm_naming import MLLMSegmentNamer
from tests import llm_scenarios as sc
from tests.test_server_fixtures import scene

RECORDING = bool(os.environ.get(RECORD_ENV))
CASSETTE = "segment_naming.jsonl"


def test_the_mllm_names_the_segments_and_they_become_instances_and_a_region():
    with OllamaReplayServer(
        sc.CASSETTES / CASSETTE, record_from_env=True, record_command=sc.record_command(CASSETTE)
    ) as server:
        result = sc.segment_naming(server.host)
    assert result["calls"] == 1
    labels = sorted(label for label, _ in result["instances"])
    if not RECORDING:
        golden = json.loads((sc.CASSETTES / "segment_naming.result.json").read_text())
        assert result == golden
        assert labels == ["chair", "chair", "table"]


def _frame():
    frame, _ = scenes.view(scene(), sc.SEGMENT_EYE, (0.0, 0.3, 0.4), 320, 240)
    return frame


def test_a_reply_naming_unknown_or_repeated_segments_is_sent_back_with_the_reason():
    replies = [
        {"objects": [{"segments": [1, 99], "label": "chair"}, {"segments": [1], "label": "x"}]},
        {"objects": [{"segments": [1], "label": "chair", "description": "a red chair"}]},
    ]
    calls = []

    def responder(method, path, body):
        calls.append(body)
        return 200, chat_reply(body["model"], json.dumps(replies[len(calls) - 1]))

    with Transcript() as transcript, ScriptedOllama(responder) as model:
        client = OllamaClient(
            sc.MODEL, host=model.host, retries=0, vision=True, transcript=transcript
        )
        semantics = MLLMSegmentNamer(client)(_frame())
    assert [o.label for o in semantics.objects] == ["chair"]
    retry = calls[1]["messages"][-1]["content"]
    assert "[99] do not exist" in retry and "[1] are used by more than one object" in retry
    assert calls[0]["messages"][0]["images"], "the contact sheet goes to the model"
    requests = [e for e in transcript.events if e["kind"] == "llm_request"]
    assert requests[0]["prompt"].startswith("segment_naming@")


def test_a_model_that_keeps_naming_unknown_segments_is_a_clear_error():
    def responder(method, path, body):
        return 200, chat_reply(body["model"], '{"objects": [{"segments": [77], "label": "x"}]}')

    with ScriptedOllama(responder) as model:
        client = OllamaClient(sc.MODEL, host=model.host, retries=0, vision=True)
        with pytest.raises(LLMOutputError, match=r"segment ids \[77\] do not exist"):
            MLLMSegmentNamer(client)(_frame())


def test_glmap_build_with_geometric_mllm_names_the_redwood_segments_through_ollama(tmp_path):
    import re

    from glmap_tools.cli import main as glmap_main
    from glmap_tools.language.embed import HashingEmbedder
    from glmap_tools.map import GLMap

    calls = []

    def largest_is_a_chair(method, path, body):  # the first line is the largest segment
        calls.append(body)
        first = re.search(r"^(\d+): ", body["messages"][0]["content"], re.MULTILINE)
        objects = [{"segments": [int(first.group(1))], "label": "chair"}] if first else []
        return 200, chat_reply(body["model"], json.dumps({"objects": objects}))

    out = tmp_path / "rw.glmap"
    with ScriptedOllama(largest_is_a_chair) as model:
        code = glmap_main(
            ["build", "--out", str(out), "--quiet", "--embedder", "hashing"]
            + ["--perception", "geometric+mllm", "--ollama-host", model.host]
            + ["--llm-model", "a-vision-model"]
        )
    assert code == 0 and len(calls) == 5
    assert all(body["model"] == "a-vision-model" for body in calls)
    glmap = GLMap.open(out, embedder=HashingEmbedder())
    try:
        assert {u.label for u in glmap.instances.values()} == {"chair"}
    finally:
        glmap.close()
