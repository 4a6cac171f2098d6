"""A client's model for the sampling tests: a `sampling_callback` that answers from recordings.

`RecordedModel` answers each `sampling/createMessage` from a cassette (the
glmap-ollama-cassette format of glmap_tools.language.ollama_replay, tests/cassettes):

- a sampling cassette (`path` "sampling/createMessage"): the request's messages and system
  prompt are the key; the reply is the recorded `CreateMessageResult`;
- an Ollama cassette (`path` "/api/chat"): the request's text is matched to the recorded
  Ollama request's message text, and the recorded answer's content comes back. The server
  uses the same prompt files for sampling as for Ollama, so the Ollama path's recordings
  answer the sampling path's requests word for word.

A request that no recording holds is answered with an error naming the closest one (and
counted in `misses`), so a test fails where the prompt changed.

    python -m tests.sampling_replay     # rewrite the sampling cassettes (scripted stand-ins)
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

from mcp import types

from glmap_tools.language.ollama_replay import Cassette, canonical, request_key, write_cassette

CASSETTES = Path(__file__).parent / "cassettes"
SAMPLING_PATH = "sampling/createMessage"
NAV_CASSETTE = "sampling_nav.jsonl"
NAV_GOAL = "sofa"
SITUATION_CASSETTE = "sampling_situation.jsonl"
SITUATION = "I am sitting on the red wooden chair, facing the dining table."
HAND_WRITTEN = (
    "written by hand: replies from a scripted stand-in (tests/sampling_replay.py, keyword "
    "rules, no language model); replace with a real recording"
)
RECORD = ".venv/bin/python -m tests.sampling_replay"


def request_body(params: types.CreateMessageRequestParams) -> dict[str, Any]:
    """A sampling request as a cassette stores it: roles and texts (images by count)."""
    messages = []
    for m in params.messages:
        content = m.content
        text = content.text if isinstance(content, types.TextContent) else f"[{content.type}]"
        messages.append({"role": m.role, "content": text})
    return {"messages": messages, "system": params.system_prompt}


def reply(text: str, model: str = "scripted") -> types.CreateMessageResult:
    return types.CreateMessageResult(
        role="assistant", content=types.TextContent(type="text", text=text), model=model
    )


class RecordedModel:
    """A `sampling_callback` answering from cassettes; see the module docstring.

    Attributes:
        requests: the request bodies received, in order.
        misses: the requests no recording held.
    """

    def __init__(self, *names: str) -> None:
        self.by_key: dict[str, dict[str, Any]] = {}
        self.by_text: dict[str, str] = {}
        self.cassettes = [Cassette.load(CASSETTES / n) for n in names]
        for cassette in self.cassettes:
            for ex in cassette.exchanges:
                request = ex["request"]
                if request["path"] == SAMPLING_PATH:
                    self.by_key[ex["key"]] = ex["response"]["body"]
                else:  # an Ollama /api/chat exchange: its user text -> the reply's content
                    text = "\n".join(m["content"] for m in request["body"]["messages"])
                    self.by_text[text] = ex["response"]["body"]["message"]["content"]
        self.requests: list[dict[str, Any]] = []
        self.misses: list[str] = []

    async def __call__(
        self, context: Any, params: types.CreateMessageRequestParams
    ) -> types.CreateMessageResult | types.ErrorData:
        body = request_body(params)
        self.requests.append(body)
        key = request_key("POST", SAMPLING_PATH, body)
        if key in self.by_key:
            return types.CreateMessageResult.model_validate(self.by_key[key])
        # The Ollama path sends an image inside its message; sampling as a message of its own.
        text = "\n".join(m["content"] for m in body["messages"] if m["content"] != "[image]")
        if text in self.by_text:
            return reply(self.by_text[text], "recorded")
        closest = ""
        for cassette in self.cassettes:
            index, ratio, diff = cassette.closest("POST", SAMPLING_PATH, body)
            if index >= 0:
                closest = f"; closest #{index + 1} in {cassette.path.name} ({ratio:.2f}): {diff}"
        self.misses.append(text[:300] + closest)
        return types.ErrorData(code=-32000, message=f"no recorded reply{closest}; run {RECORD}")


# ------------------------------------------------------------ scripted stand-in


def keyword_scores(params: types.CreateMessageRequestParams) -> types.CreateMessageResult:
    """Plays a scorer: 0.92 for a unit whose text holds the goal's word, else 0.05."""
    text = request_body(params)["messages"][0]["content"]
    goal = re.search(r'for: "(.*?)"', text).group(1).lower()  # type: ignore[union-attr]
    units = re.findall(r"^(\d+): (.*)$", text, re.MULTILINE)
    scores = [
        {"id": int(uid), "probability": 0.92 if goal in line.lower() else 0.05}
        for uid, line in units
    ]
    return reply(json.dumps({"scores": scores}))


def situation_reading(params: types.CreateMessageRequestParams) -> types.CreateMessageResult:
    """Plays a reader: the offline reader's reading of the quoted situation, posture added."""
    from glmap_tools.sqa.reading import read_situation

    text = request_body(params)["messages"][0]["content"]
    situation = re.search(r'home: "(.*)"\.', text).group(1)  # type: ignore[union-attr]
    reading = read_situation(situation).as_dict()
    reading["posture"] = "sitting" if "sitting" in situation else reading["posture"]
    return reply(json.dumps({"reading": reading, "scores": []}))


class Recorder:
    """A `sampling_callback` that answers with `responder` and keeps every exchange."""

    def __init__(self, responder: Any) -> None:
        self.responder = responder
        self.exchanges: list[tuple[str, str, Any, int, Any]] = []

    async def __call__(self, context: Any, params: types.CreateMessageRequestParams) -> Any:
        result = self.responder(params)
        body = canonical(request_body(params))
        dumped = result.model_dump(mode="json", by_alias=True, exclude_none=True)
        self.exchanges.append(("POST", SAMPLING_PATH, body, 200, dumped))
        return result


async def nav_episode(client: Any) -> dict[str, Any]:
    """The episode the nav test plays: sim_reset (goal NAV_GOAL), two turns, value_map."""
    await client.call_tool("sim_reset", {"scene": 0, "seed": 0, "goal": NAV_GOAL})
    for _ in range(2):
        await client.call_tool("sim_step", {"action": "turn_left"})
    result = await client.call_tool("value_map", {})
    return json.loads(result.content[0].text)  # type: ignore[no-any-return]


async def situated(client: Any) -> dict[str, Any]:
    """The call the reading test makes: the fixture scene observed, then locate_situation."""
    from tests.test_server_fixtures import frame_args

    await client.call_tool("observe_frame", frame_args())
    result = await client.call_tool("locate_situation", {"situation": SITUATION})
    return json.loads(result.content[0].text)  # type: ignore[no-any-return]


def _write(name: str, recorder: Recorder) -> None:
    unique = {request_key(m, p, b): (m, p, b, s, r) for m, p, b, s, r in recorder.exchanges}
    write_cassette(CASSETTES / name, list(unique.values()), source=HAND_WRITTEN, record=RECORD)
    print(f"wrote {CASSETTES / name}: {len(unique)} exchanges")


def write_situation_cassette(maps_dir: Path) -> None:
    """Play `situated` against the scripted reader and write tests/cassettes/SITUATION."""
    import anyio
    from mcp import Client

    from glmap_tools.language.backends import LLMSettings
    from glmap_tools.server import build_server
    from tests.test_server_fixtures import config

    recorder = Recorder(situation_reading)

    async def play() -> None:
        server = build_server(config(maps_dir, llm=LLMSettings(reader="sampling")))
        async with Client(server, sampling_callback=recorder, mode="legacy") as client:
            await situated(client)

    anyio.run(play)
    _write(SITUATION_CASSETTE, recorder)


def write_nav_cassette(maps_dir: Path) -> None:
    """Play `nav_episode` against the scripted stand-in and write tests/cassettes/NAV."""
    import anyio
    from mcp import Client

    from glmap_tools.language.backends import LLMSettings
    from glmap_tools.server import build_server
    from tests.test_server_fixtures import config

    recorder = Recorder(keyword_scores)

    async def play() -> None:
        server = build_server(config(maps_dir, llm=LLMSettings(scorer="sampling")))
        async with Client(server, sampling_callback=recorder, mode="legacy") as client:
            await nav_episode(client)

    anyio.run(play)
    _write(NAV_CASSETTE, recorder)


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        write_nav_cassette(Path(folder) / "nav")
        write_situation_cassette(Path(folder) / "situation")
    sys.exit(0)
