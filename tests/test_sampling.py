"""The calling client's model as GLMap's LLM (MCP sampling), through a real client session.

The client declares sampling with a callback that answers from recordings
(tests/sampling_replay.py): the sampling cassette of a short episode, and the Ollama
path's own cassettes, whose prompts the sampling path sends word for word.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
from pathlib import Path
from typing import Any

import anyio
import numpy as np
import pytest
from mcp import Client, types

from glmap_tools import synthetic
from glmap_tools.app.frames import observe_arguments
from glmap_tools.errors import LLMError, LLMUnavailableError
from glmap_tools.language.backends import LLMSettings, make_scorer
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.llm import LLMReply
from glmap_tools.language.sampling import (
    FallbackScorer,
    SamplingClient,
    SamplingUsage,
    bind,
    usage_report,
)
from glmap_tools.nav.scorers import UnitText
from glmap_tools.perception.backends import model_perception
from glmap_tools.server import build_server
from glmap_tools.server.cli import build_parser, config_from_args
from tests import llm_scenarios as sc
from tests.sampling_replay import (
    NAV_CASSETTE,
    NAV_GOAL,
    SITUATION_CASSETTE,
    RecordedModel,
    nav_episode,
    situated,
)
from tests.test_server_fixtures import config, scene

pytestmark = pytest.mark.anyio
SAMPLING = LLMSettings(scorer="sampling", text_merger="sampling")


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def ok(result: Any) -> dict[str, Any]:
    assert not result.is_error, result.content[0].text
    return json.loads(result.content[0].text)  # type: ignore[no-any-return]


def recorded_scores(model: RecordedModel) -> dict[str, float]:
    """unit text -> the probability the recording gave it."""
    out: dict[str, float] = {}
    for ex in model.cassettes[0].exchanges:
        prompt = ex["request"]["body"]["messages"][0]["content"]
        lines = dict(ln.split(": ", 1) for ln in prompt.splitlines() if ln[:1].isdigit())
        scores = json.loads(ex["response"]["body"]["content"]["text"])["scores"]
        out.update({lines[str(s["id"])]: s["probability"] for s in scores})
    return out


async def test_the_client_model_scores_units_and_its_scores_reach_the_value_map(tmp_path):
    model = RecordedModel(NAV_CASSETTE)
    server = build_server(config(tmp_path, llm=LLMSettings(scorer="sampling")))
    async with Client(server, sampling_callback=model, mode="legacy") as client:
        value = await nav_episode(client)
        step = ok(await client.call_tool("sim_step", {"action": "turn_right"}))
    assert model.requests and not model.misses, model.misses
    prompts = [r["messages"][0]["content"] for r in model.requests]
    assert all(p.startswith(f'A robot is searching a home for: "{NAV_GOAL}"') for p in prompts)
    # The value map ranks the units by the client's probabilities (the recording's 0.92 for
    # the sofa and its seating area, 0.05 for the rest), not by the embedder's cosine.
    top = value["top_units"]
    recorded = set(recorded_scores(model).values())
    assert recorded == {0.92, 0.05}
    assert top and top[0][2] == pytest.approx(0.92)
    assert all(round(u[2], 3) in recorded for u in top), top
    assert step["llm"]["sampling_calls"] == len(model.requests)
    assert step["llm"]["est_prompt_tokens"] > 0 and step["llm"]["fallbacks"] == 0


async def test_a_unit_text_scored_once_for_a_goal_costs_no_second_sampling_call(tmp_path):
    model = RecordedModel(NAV_CASSETTE)
    server = build_server(config(tmp_path, llm=LLMSettings(scorer="sampling")))
    async with Client(server, sampling_callback=model, mode="legacy") as client:
        first = await nav_episode_without_reset(client, model)
        calls = len(model.requests)
        again = ok(await client.call_tool("value_map", {}))
        assert len(model.requests) == calls  # the same goal and unit texts: from the cache
    assert again["top_units"] == first["top_units"]


async def nav_episode_without_reset(client: Client, model: RecordedModel) -> dict[str, Any]:
    value = await nav_episode(client)
    assert model.requests and not model.misses, model.misses
    return value


async def test_a_refused_sampling_request_falls_back_to_the_embedder_and_says_so(tmp_path, caplog):
    asked: list[str] = []

    async def refuse(context: Any, params: types.CreateMessageRequestParams) -> Any:
        asked.append(params.messages[0].content.text)  # type: ignore[union-attr]
        return types.ErrorData(code=-1, message="the user declined")

    server = build_server(config(tmp_path, llm=LLMSettings(scorer="sampling")))
    with caplog.at_level(logging.WARNING, logger="glmap_tools.sampling"):
        async with Client(server, sampling_callback=refuse, mode="legacy") as client:
            value = await nav_episode(client)
            step = ok(await client.call_tool("sim_step", {"action": "turn_right"}))
    assert asked  # the client was asked, and said no
    assert value["top_units"]  # scored all the same, by the embedder
    assert step["llm"]["fallbacks"] >= 1 and step["llm"]["sampling_failed"] >= 1
    said = step["llm"]["last_fallback"]
    assert "declined" in said and "embedding scorer" in said
    assert any("used the embedding scorer instead" in r.getMessage() for r in caplog.records)


async def test_a_connection_without_a_back_channel_falls_back_and_says_why(tmp_path):
    model = RecordedModel(NAV_CASSETTE)
    server = build_server(config(tmp_path, llm=LLMSettings(scorer="sampling")))
    async with Client(server, sampling_callback=model) as client:  # 2026-07-28: stateless
        await client.call_tool("sim_reset", {"scene": 0, "seed": 0, "goal": NAV_GOAL})
        step = ok(await client.call_tool("sim_step", {"action": "turn_left"}))
    assert not model.requests
    assert "no back-channel" in step["llm"]["last_fallback"]


async def test_a_client_without_sampling_gets_the_fallback_and_no_request(tmp_path):
    server = build_server(config(tmp_path, llm=LLMSettings(scorer="sampling")))
    async with Client(server, mode="legacy") as client:
        await client.call_tool("sim_reset", {"scene": 0, "seed": 0, "goal": NAV_GOAL})
        step = ok(await client.call_tool("sim_step", {"action": "turn_left"}))
    assert step["llm"]["sampling_calls"] == 0
    assert "did not declare" in step["llm"]["last_fallback"]


async def test_a_client_model_that_does_not_answer_in_time_falls_back(tmp_path):
    never = anyio.Event()

    async def silent(context: Any, params: types.CreateMessageRequestParams) -> Any:
        await never.wait()  # the client's model never answers

    settings = LLMSettings(scorer="sampling", sampling_timeout=0.3)
    server = build_server(config(tmp_path, llm=settings))
    async with Client(server, sampling_callback=silent, mode="legacy") as client:
        reset = ok(await client.call_tool("sim_reset", {"scene": 0, "seed": 0, "goal": NAV_GOAL}))
        never.set()
    assert "no answer within 0.3 s" in reset["llm"]["last_fallback"]


async def test_a_text_buffer_past_its_limit_is_merged_by_the_client_model(tmp_path):
    # The Ollama path's recording answers: the sampling path sends the same prompt.
    model = RecordedModel("map_text_merge.jsonl")
    server = build_server(config(tmp_path, llm=LLMSettings(text_merger="sampling")))
    boxes = synthetic.floor() + synthetic.chair(0.0, 0.0)  # the Ollama scenario's chair
    frame, ids = synthetic.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3), 160, 120)
    async with Client(server, sampling_callback=model, mode="legacy") as client:
        for text in sc.chair_descriptions(12):
            objects = [{"id": 1, "label": "chair", "description": text}]
            args = observe_arguments(frame, ids, objects, [])
            assert not (await client.call_tool("observe_frame", args)).is_error
        found = await client.call_tool("find_instance", {"query": "chair", "top_k": 1})
    assert model.requests and not model.misses, model.misses
    assert "Merge them into one description" in model.requests[0]["messages"][0]["content"]
    assert sc.CHAIR_BASE in json.dumps(found.structured_content)


async def test_the_client_model_names_the_segments_of_a_frame_from_its_contact_sheet(tmp_path):
    model = RecordedModel("segment_naming.jsonl")  # the Ollama path's recording
    settings = LLMSettings(mllm="sampling")
    server = build_server(
        config(tmp_path, llm=settings), model_perception("geometric+mllm", settings)
    )
    frame, _ = synthetic.view(scene(), sc.SEGMENT_EYE, (0.0, 0.3, 0.4), 320, 240)
    async with Client(server, sampling_callback=model, mode="legacy") as client:
        observed = await client.call_tool("observe_frame", observe_arguments(frame, None, [], []))
        assert not observed.is_error, observed.content[0].text
        found = await client.call_tool("find_instance", {"query": "table", "top_k": 3})
    assert model.requests and not model.misses, model.misses
    assert [m["content"] for m in model.requests[0]["messages"]][0] == "[image]"  # the sheet
    expected = json.loads((sc.CASSETTES / "segment_naming.result.json").read_text())
    labels = sorted(h["label"] for h in found.structured_content["hits"])  # type: ignore[index]
    assert labels == sorted(label for label, _ in expected["instances"])


async def test_segments_the_client_model_does_not_name_stay_pending_for_label_segments(
    tmp_path, caplog
):
    async def refuse(context: Any, params: types.CreateMessageRequestParams) -> Any:
        return types.ErrorData(code=-1, message="the user declined")

    settings = LLMSettings(mllm="sampling")
    server = build_server(
        config(tmp_path, llm=settings), model_perception("geometric+mllm", settings)
    )
    frame, _ = synthetic.view(scene(), sc.SEGMENT_EYE, (0.0, 0.3, 0.4), 320, 240)
    with caplog.at_level(logging.WARNING, logger="glmap_tools.sampling"):
        async with Client(server, sampling_callback=refuse, mode="legacy") as client:
            observed = await client.call_tool(
                "observe_frame", observe_arguments(frame, None, [], [])
            )
    assert not observed.is_error, observed.content[0].text
    assert "label_segments" in observed.content[0].text
    assert any("used pending segments" in r.getMessage() for r in caplog.records)


async def test_the_client_model_reads_the_situation_that_locate_situation_places(tmp_path):
    model = RecordedModel(SITUATION_CASSETTE)
    server = build_server(config(tmp_path, llm=LLMSettings(reader="sampling")))
    async with Client(server, sampling_callback=model, mode="legacy") as client:
        info = await situated(client)
    assert model.requests and not model.misses, model.misses
    recorded = model.cassettes[0].exchanges[0]["response"]["body"]["content"]["text"]
    assert info["read_by"] == "the client's model (sampling)"
    assert info["situation"]["reading"] == json.loads(recorded)["reading"]
    assert info["situation"]["reading"]["posture"] == "sitting"  # the rule reader has none


async def test_a_situation_the_client_model_cannot_read_is_read_by_the_rules(tmp_path, caplog):
    server = build_server(config(tmp_path, llm=LLMSettings(reader="sampling")))
    with caplog.at_level(logging.WARNING, logger="glmap_tools.sampling"):
        async with Client(server, mode="legacy") as client:  # no sampling declared
            info = await situated(client)
    assert info["read_by"] == "rules (fallback)" and info["situation"]["reading"]["anchor"]
    assert any("used the rule reader instead" in r.getMessage() for r in caplog.records)


# ------------------------------------------------------------ without MCP


def test_sampling_client_asks_the_bound_sampler_on_the_loop_from_a_worker_thread():
    seen: list[tuple[str | None, str]] = []

    async def sampler(messages: Any, *, system: Any = None, **kw: Any) -> LLMReply:
        seen.append((system, messages[0]["content"]))
        return LLMReply('{"scores": [{"id": 1, "probability": 0.7}]}', model="m")

    async def main() -> np.ndarray:
        usage = SamplingUsage()
        bind(sampler, usage)
        scorer = make_scorer(LLMSettings(scorer="sampling"), HashingEmbedder())
        units = [UnitText(1, "instance", "a bed")]
        result = await anyio.to_thread.run_sync(lambda: scorer.score("bed", units))
        assert usage.calls == 1 and usage_report()["sampling_calls"] == 1
        assert threading.current_thread() is threading.main_thread()
        return result

    scores = asyncio.run(main())
    assert scores.tolist() == [0.7] and seen and "a bed" in seen[0][1]


def test_sampling_on_the_event_loop_thread_is_an_error_not_a_deadlock():
    async def sampler(messages: Any, **kw: Any) -> LLMReply:
        return LLMReply("{}")

    async def main() -> None:
        bind(sampler, SamplingUsage())
        with pytest.raises(LLMError, match="event loop"):
            SamplingClient().chat([{"role": "user", "content": "hi"}])

    asyncio.run(main())


def test_outside_a_tool_call_sampling_is_unavailable_and_fallback_none_raises():
    with pytest.raises(LLMUnavailableError, match="sampling capability"):
        SamplingClient().chat([{"role": "user", "content": "hi"}])
    scorer = make_scorer(LLMSettings(scorer="sampling", fallback="none"), HashingEmbedder())
    assert isinstance(scorer, FallbackScorer) and scorer.fallback is None
    with pytest.raises(LLMUnavailableError):
        scorer.score("bed", [UnitText(1, "instance", "a bed")])


def test_glmap_mcp_llm_sampling_sets_both_parts_and_the_fallback(tmp_path: Path):
    args = build_parser().parse_args(
        ["--llm", "sampling", "--llm-fallback", "ollama", "--sampling-timeout", "5"]
    )
    llm = config_from_args(args).llm
    assert (llm.scorer, llm.text_merger, llm.fallback) == ("sampling", "sampling", "ollama")
    assert llm.sampling_timeout == 5 and llm.uses_sampling and llm.uses_llm
    plain = config_from_args(build_parser().parse_args(["--scorer", "sampling"])).llm
    assert (plain.scorer, plain.text_merger) == ("sampling", "extractive")
    assert not config_from_args(build_parser().parse_args([])).llm.uses_sampling


def test_with_fallback_ollama_a_failed_sampling_request_asks_the_ollama_model():
    from glmap_tools.language.ollama_replay import ScriptedOllama

    with ScriptedOllama(sc.keyword_scores) as ollama:
        settings = LLMSettings(scorer="sampling", fallback="ollama", host=ollama.host)
        scorer = make_scorer(settings, HashingEmbedder())
        scores = scorer.score("tv", sc.NAV_UNITS)  # outside a tool call: no client to ask
    assert ollama.requests and scorer.fallback_name == "ollama"
    np.testing.assert_allclose(scores, [0.92, 0.05, 0.92, 0.92, 0.05])


async def answer_situated(client: Client) -> dict[str, Any]:
    """The Ollama path's SQA scenario (tests/llm_scenarios.sqa_mllm) over MCP."""
    from tests.test_server_fixtures import frame_args

    for eye in ((0.0, -2.6, 1.4), (-2.5, 1.5, 1.4)):
        assert not (await client.call_tool("observe_frame", frame_args(eye))).is_error
    args = {"situation": sc.SQA_SITUATION, "question": sc.SQA_QUESTION}
    return ok(await client.call_tool("locate_situation", args))


async def test_the_client_model_answers_the_situated_question_from_the_four_views(tmp_path):
    model = RecordedModel("sqa_mllm.jsonl")  # the Ollama path's recording answers
    server = build_server(config(tmp_path, llm=LLMSettings(answerer="sampling")))
    async with Client(server, sampling_callback=model, mode="legacy") as client:
        info = await answer_situated(client)
    assert model.requests and not model.misses, model.misses
    assert [m["content"] for m in model.requests[0]["messages"]][0] == "[image]"  # the views
    recorded = json.loads(model.cassettes[0].exchanges[0]["response"]["body"]["message"]["content"])
    assert info["model_answer"] == {**recorded, "by": "the client's model (sampling)"}
    assert info["map_answer"]["answer"]  # the map's own answer stays beside it
    assert info["llm"]["sampling_calls"] == 1 and info["llm"]["fallbacks"] == 0


async def test_a_question_the_client_model_cannot_answer_keeps_the_map_answer(tmp_path, caplog):
    server = build_server(config(tmp_path, llm=LLMSettings(answerer="sampling")))
    with caplog.at_level(logging.WARNING, logger="glmap_tools.sampling"):
        async with Client(server, mode="legacy") as client:  # no sampling declared
            info = await answer_situated(client)
    assert "model_answer" not in info and info["map_answer"]["answer"]
    assert any("used the map's answer instead" in r.getMessage() for r in caplog.records)


@pytest.mark.slow  # starts glmap-mcp as a client does (~10 s on two busy cores)
async def test_glmap_mcp_over_stdio_asks_the_client_model_when_started_with_llm_sampling(
    tmp_path,
):
    import os
    import sys

    from mcp import StdioServerParameters

    model = RecordedModel(NAV_CASSETTE)
    params = StdioServerParameters(
        command=sys.executable,
        args=["-m", "glmap_tools.server", "--llm", "sampling", "--maps-dir", str(tmp_path)]
        + ["--embedder", "hashing", "--voxel-size", "0.04", "--no-warm-up"],
        env={k: v for k, v in os.environ.items() if k in ("PYTHONPATH", "PYOPENGL_PLATFORM")},
    )
    # The handshake relay answers `initialize` first; the SDK still learns the client's
    # capabilities, and the client's answers reach the server through it.
    async with Client(params, sampling_callback=model, mode="legacy") as client:
        value = await nav_episode(client)
    assert model.requests and not model.misses, model.misses
    assert value["top_units"][0][2] == pytest.approx(0.92)


def test_an_in_process_toolset_asks_the_sampler_its_user_gives(tmp_path):
    from glmap_tools.toolset import Toolset

    asked: list[str] = []

    async def sampler(messages: Any, **kw: Any) -> LLMReply:
        asked.append(messages[0]["content"])
        ids = [ln.split(":")[0] for ln in messages[0]["content"].splitlines() if ln[:1].isdigit()]
        scores = [{"id": int(i), "probability": 0.25} for i in ids]
        return LLMReply(json.dumps({"scores": scores}), model="mine")

    settings = LLMSettings(scorer="sampling")
    with Toolset(config(tmp_path, llm=settings), sampler=sampler) as tools:
        reset = tools.call("sim_reset", {"scene": 0, "seed": 0, "goal": NAV_GOAL})
    assert asked and reset.data.llm.sampling_calls == len(asked)
    assert reset.data.llm.fallbacks == 0
