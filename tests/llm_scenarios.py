"""The LLM-backed scenarios the replay tests run, and the script that writes their cassettes.

Each scenario runs real code (OllamaClient, LLMScorer, LLMTextMerger, GLMap) against an
Ollama at `host`. The tests point `host` at a replay server over tests/cassettes/*.jsonl.

    python -m tests.llm_scenarios            # rewrite the hand-written cassettes
    GLMAP_OLLAMA_RECORD=http://127.0.0.1:11434 .venv/bin/python -m pytest tests/test_llm_replay.py
                                             # record the re-recordable ones from a live Ollama

The hand-written cassettes come from `ScriptedOllama`: a Python function plays the model
(keyword rules, no language model), and each file's header says so. Fault cassettes
(malformed replies, a missing model) can only be written by hand.
"""

from __future__ import annotations

import contextlib
import json
import re
import sys
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from glmap_tools import synthetic as scenes
from glmap_tools.errors import LLMError
from glmap_tools.language.embed import HashingEmbedder
from glmap_tools.language.llm import OllamaClient
from glmap_tools.language.llm_merger import LLMTextMerger
from glmap_tools.language.llm_scorer import LLMScorer
from glmap_tools.language.ollama_replay import (
    OllamaReplayServer,
    ScriptedOllama,
    chat_reply,
)
from glmap_tools.map import GLMap, MapConfig
from glmap_tools.nav.scorers import UnitText

CASSETTES = Path(__file__).parent / "cassettes"
MODEL = "qwen3:8b"
HAND_WRITTEN = (
    "written by hand: replies from a scripted stand-in (tests/llm_scenarios.py, keyword "
    "rules, no language model); replace with a real recording"
)


def record_command(cassette: str) -> str:
    """The command that re-records `cassette` from a live Ollama."""
    return (
        "GLMAP_OLLAMA_RECORD=http://127.0.0.1:11434 .venv/bin/python -m pytest "
        f"tests/test_llm_replay.py -k {Path(cassette).stem}"
    )


def client(host: str, **kw: Any) -> OllamaClient:
    return OllamaClient(MODEL, host=host, retries=0, backoff=0.01, **kw)


# ------------------------------------------------------------------- scenarios

NAV_UNITS = [
    UnitText(1, "instance", "a black flat-screen television on a low cabinet"),
    UnitText(2, "instance", "a white bathtub with a chrome tap"),
    UnitText(3, "instance", "a grey fabric sofa facing the tv"),
    UnitText(11, "region", "living room with a sofa, a coffee table and a tv"),
    UnitText(12, "region", "bathroom with a bathtub and a sink"),
]


def nav_scores(host: str) -> np.ndarray:
    """f_S of five units for the goal 'tv' (two calls: instances, regions)."""
    return LLMScorer(client(host)).score("tv", NAV_UNITS)


CHAIR_BASE = "a wooden chair with a red cushion and four legs standing near the table"


def chair_descriptions(n: int) -> list[str]:
    return [f"{CHAIR_BASE} " + " ".join(f"detail{k}x{w}" for w in range(16)) for k in range(n)]


def map_text_merge(host: str) -> GLMap:
    """A chair seen 12 times with 30-word descriptions: the LLM merger runs past 300 words."""
    glmap = GLMap(
        MapConfig(floor_z=0.0),
        embedder=HashingEmbedder(),
        text_merger=LLMTextMerger(client(host)),
    )
    boxes = scenes.floor() + scenes.chair(0.0, 0.0)
    frame, ids = scenes.view(boxes, (0.0, -2.5, 1.3), (0.0, 0.0, 0.3), 160, 120)
    for text in chair_descriptions(12):
        glmap.integrate(frame, scenes.semantics(ids, {1: ("chair", text)}))
    return glmap


# ------------------------------------------------------------ scripted stand-in


def _prompt_units(body: dict) -> list[tuple[int, str]]:
    text = body["messages"][0]["content"]
    return [(int(m[1]), m[2]) for m in re.finditer(r"^(\d+): (.*)$", text, re.MULTILINE)]


def keyword_scores(method: str, path: str, body: Any) -> tuple[int, Any]:
    """Plays a scorer: 0.92 when a unit mentions the goal's words, 0.3 for a living room."""
    goal = re.search(r'for: "(.*?)"', body["messages"][0]["content"]).group(1)  # type: ignore[union-attr]
    words = {goal.lower(), "television"} if goal.lower() == "tv" else {goal.lower()}
    scores = []
    for uid, text in _prompt_units(body):
        low = text.lower()
        p = 0.92 if any(w in low for w in words) else 0.3 if "living" in low else 0.05
        if "sofa" in low and p < 0.5:
            p = 0.4
        scores.append({"id": uid, "probability": p})
    return 200, chat_reply(body["model"], json.dumps({"scores": scores}))


def merge_first_sentence(method: str, path: str, body: Any) -> tuple[int, Any]:
    """Plays the merger: keeps the shared opening words and the first detail of each line."""
    lines = [ln[2:] for ln in body["messages"][0]["content"].splitlines() if ln.startswith("- ")]
    details = [ln.split()[-16] for ln in lines if ln.split()[-16].startswith("detail")]
    merged = CHAIR_BASE + "; details " + ", ".join(dict.fromkeys(details))
    return 200, chat_reply(body["model"], json.dumps({"description": merged}))


def write(name: str, scenario: Callable[[str], Any], responder: Any, source: str) -> None:
    """Run `scenario` against the scripted stand-in, recording into tests/cassettes/name."""
    with (
        ScriptedOllama(responder) as model,
        OllamaReplayServer(
            CASSETTES / name, upstream=model.host, record_command=record_command(name)
        ) as proxy,
    ):
        result = scenario(proxy.host)
        proxy.cassette.header["source"] = source
    print(f"wrote {CASSETTES / name}: {len(proxy.cassette.exchanges)} exchanges")
    if isinstance(result, dict):  # the outcome a replay must reach again
        keep = {k: v for k, v in result.items() if k not in ("wall_s",)}
        golden = CASSETTES / name.replace(".jsonl", ".result.json")
        golden.write_text(json.dumps(keep, indent=1, sort_keys=True) + "\n")


AGENT_EPISODE = "tune/objectnav/s00-000"
AGENT_SEED = 0


def agent_episode(host: str, out_dir: Path | None = None) -> dict[str, Any]:
    """One ObjectNav episode of the tool-calling agent on a tune-split episode."""
    import asyncio
    import tempfile

    from agents.llm_agent import Budget, run_llm_episode
    from agents.runner import open_session
    from glmap_tools.map import MapConfig as _MapConfig
    from glmap_tools.server import ServerConfig

    async def play(folder: Path) -> dict[str, Any]:
        config = ServerConfig(
            maps_dir=folder / "maps",
            embedder="hashing",
            map_config=_MapConfig(voxel_size=0.04),
            warm_up=False,
        )
        async with open_session(config) as session:
            return await run_llm_episode(
                session,
                AGENT_EPISODE,
                client(host),
                seed=AGENT_SEED,
                out_dir=folder / "episode",
                budget=Budget(max_turns=12),
                max_steps=50,
                image_size="160x120",
            )

    if out_dir is not None:
        return asyncio.run(play(out_dir))
    with tempfile.TemporaryDirectory() as tmp:
        return asyncio.run(play(Path(tmp)))


def scripted_navigator(method: str, path: str, body: Any) -> tuple[int, Any]:
    """Plays the tool agent by fixed rules (no model): look around, then alternate value_map
    and navigate_to towards its waypoint; stop when the waypoint is the goal and reached."""
    msgs = body["messages"]
    tools = [m for m in msgs if m["role"] == "tool"]
    model = body["model"]
    if not tools:
        return 200, chat_reply(model, "", [("look_around", {})])
    last = tools[-1]
    data = json.loads(last["content"]) if last["content"].startswith("{") else {}
    if last.get("tool_name") == "value_map":
        w = data.get("waypoint") or {}
        if w.get("kind") == "goal" and float(w.get("distance_m", 9.0)) < 0.3:
            return 200, chat_reply(model, "", [("sim_step", {"action": "stop"})])
        if w.get("kind") in (None, "none"):
            return 200, chat_reply(model, "", [("sim_step", {"action": "turn_left"})])
        x, y = w["xy"]
        return 200, chat_reply(model, "", [("navigate_to", {"x": x, "y": y, "max_steps": 25})])
    return 200, chat_reply(model, "", [("value_map", {})])


SQA_SITUATION = "I am standing next to the dining table, facing the blue chair"
SQA_QUESTION = "What is in front of me?"


def sqa_mllm(host: str, views: str = "four") -> Any:
    """One situated question answered by the MLLM from locate_situation's views (and, with
    views='both', the top-down crop with unit ids)."""
    import asyncio
    import tempfile

    from mcp import Client

    from agents.sqa import answer
    from glmap_tools.server import build_server
    from tests.test_server_fixtures import config, frame_args

    async def run(folder: Path) -> Any:
        async with Client(build_server(config(folder))) as mcp_client:
            for eye in ((0.0, -2.6, 1.4), (-2.5, 1.5, 1.4)):
                await mcp_client.call_tool("observe_frame", frame_args(eye))
            llm = OllamaClient(MODEL, host=host, retries=0, vision=True)
            return await answer(mcp_client, SQA_SITUATION, SQA_QUESTION, llm, views=views)

    with tempfile.TemporaryDirectory() as tmp:
        return asyncio.run(run(Path(tmp)))


def scripted_sqa(method: str, path: str, body: Any) -> tuple[int, Any]:
    """Plays the MLLM: answers with the first object the map notes put in front."""
    text = body["messages"][0]["content"]
    m = re.search(r"front: ([a-z ]+?) \(", text)
    reply = {"answer": m.group(1) if m else "unknown", "confidence": 0.7}
    return 200, chat_reply(body["model"], json.dumps(reply))


SEGMENT_EYE = (0.0, -2.6, 1.4)


def segment_naming(host: str) -> dict[str, Any]:
    """The MLLM names the geometric segments of a ray-cast frame; named ones become units."""
    from glmap_tools.perception.mllm_naming import MLLMSegmentNamer
    from tests.test_server_fixtures import scene

    frame, _ = scenes.view(scene(), SEGMENT_EYE, (0.0, 0.3, 0.4), 320, 240)
    namer = MLLMSegmentNamer(OllamaClient(MODEL, host=host, retries=0, vision=True))
    glmap = GLMap(MapConfig(floor_z=0.0), embedder=HashingEmbedder())
    glmap.integrate(frame, namer(frame))
    return {
        "calls": namer.calls,
        "instances": sorted([u.label, u.text] for u in glmap.instances.values()),
        "regions": sorted(r.text for r in glmap.regions.values()),
    }


def scripted_segment_namer(method: str, path: str, body: Any) -> tuple[int, Any]:
    """Plays the MLLM from the prompt's sizes alone (it cannot see the image): wider than
    1 m is a table, a top above 0.8 m a chair; the rest is left out; one group of all."""
    lines = re.findall(
        r"^(\d+): ([\d.]+) x ([\d.]+) x ([\d.]+) m, top ([\d.-]+) m$",
        body["messages"][0]["content"],
        re.MULTILINE,
    )
    objects = []
    for sid, w, d, _, top in lines:
        wide = max(float(w), float(d))
        label = "table" if wide >= 1.0 else "chair" if float(top) >= 0.8 else None
        if label:
            desc = f"a {label} about {wide:.1f} m across and {float(top):.1f} m tall"
            objects.append({"segments": [int(sid)], "label": label, "description": desc})
    groups = [{"members": [o["segments"][0] for o in objects], "description": "a dining corner"}]
    reply = {"objects": objects, "groups": groups if objects else []}
    return 200, chat_reply(body["model"], json.dumps(reply))


SEGMENT_SOURCE = (
    "written by hand: replies from a scripted stand-in (tests/llm_scenarios.py "
    "scripted_segment_namer: size rules on the prompt's segment lines, no language model, "
    "the image unseen); replace with a real recording"
)


FAULT_REPLIES = [
    'Sure! Here are the scores:\n{"scores": [{"id": 1, "probability": 0.9}]}\nHope it helps.',
    '```json\n{"scores": [{"id": 1, "probability": 0.9}, {"id": 2, "probability": 0.02}]}\n```',
    '{"scores": [{"id": 1, "probability": 1.5}, {"id": 2, "probability": 0.8}]}',
    '{"scores": [{"id": 1, "probability": 1.5}, {"id": 2, "probability": 0.8}]}',
]


def faults(host: str) -> None:
    """Score two units for 'tv' then 'bathtub'; the replies are malformed on purpose."""
    for goal in ("tv", "bathtub"):
        with contextlib.suppress(LLMError):
            LLMScorer(client(host)).score(goal, NAV_UNITS[:2])


def scripted_faults(method: str, path: str, body: Any) -> tuple[int, Any]:
    """Plays a sloppy model: prose around JSON, a missing id, a probability of 1.5."""
    n = sum(1 for _ in scripted_faults.calls)  # type: ignore[attr-defined]
    scripted_faults.calls.append(body)  # type: ignore[attr-defined]
    return 200, chat_reply(body["model"], FAULT_REPLIES[n])


scripted_faults.calls = []  # type: ignore[attr-defined]
FAULTS_SOURCE = (
    "written by hand: malformed model replies (prose around JSON, a missing id, a "
    "probability of 1.5) for the fault tests; not re-recordable"
)


def main() -> int:
    CASSETTES.mkdir(exist_ok=True)
    write("nav_scores.jsonl", nav_scores, keyword_scores, HAND_WRITTEN)
    write("map_text_merge.jsonl", map_text_merge, merge_first_sentence, HAND_WRITTEN)
    write("faults.jsonl", faults, scripted_faults, FAULTS_SOURCE)
    write("sqa_mllm.jsonl", sqa_mllm, scripted_sqa, HAND_WRITTEN)
    write("sqa_mllm_both.jsonl", partial(sqa_mllm, views="both"), scripted_sqa, HAND_WRITTEN)
    write("agent_episode.jsonl", agent_episode, scripted_navigator, HAND_WRITTEN)
    write("segment_naming.jsonl", segment_naming, scripted_segment_namer, SEGMENT_SOURCE)
    return 0


if __name__ == "__main__":
    sys.exit(main())
