"""The sqa_situation prompt asks an LLM for the same reading as the offline reader's
(replies from a scripted stand-in over the Ollama HTTP API, no language model)."""

import json
import re

import numpy as np
import pytest

from glmap_tools.language.llm import OllamaClient
from glmap_tools.language.llm_scorer import LLMScorer
from glmap_tools.language.ollama_replay import ScriptedOllama, chat_reply
from glmap_tools.nav.scorers import UnitText
from glmap_tools.sqa.llm_reading import llm_read_situation
from glmap_tools.sqa.reading import Constraint, SituationReading, read_situation

MODEL = "qwen3:8b"
UNITS = [UnitText(1, "instance", "a grey bookshelf"), UnitText(2, "instance", "a floor lamp")]


def scripted(method, path, body):
    """Plays the model: the reading is the offline reader's, every listed id scores 0.5
    (the bookshelf 0.9)."""
    text = body["messages"][-1]["content"]
    situation = re.search(r'home: "(.*)"\.', text).group(1)
    ids = [int(i) for i in re.findall(r"^(\d+): ", text, re.MULTILINE)]
    scores = [{"id": i, "probability": 0.9 if i == 1 else 0.5} for i in ids]
    reply = {"reading": read_situation(situation).as_dict(), "scores": scores}
    return 200, chat_reply(body["model"], json.dumps(reply))


@pytest.fixture
def server():
    with ScriptedOllama(scripted) as s:
        yield s


def test_the_llm_reading_comes_back_in_the_offline_readers_form(server):
    client = OllamaClient(MODEL, host=server.host, retries=0)
    text = "I am facing a bookshelf, and a lamp is on my right."
    r = llm_read_situation(client, text)
    assert r == SituationReading(facing="bookshelf", constraints=(Constraint("lamp", "right"),))
    (_, _, body) = server.requests[-1]
    prompt = body["messages"][-1]["content"]
    assert text in prompt and "nothing to score" in prompt and '"reading"' in prompt


def test_the_scorer_still_reads_the_scores_beside_the_reading(server):
    client = OllamaClient(MODEL, host=server.host, retries=0)
    p = LLMScorer(client, mode="sqa").score("I am facing a bookshelf.", UNITS)
    assert np.allclose(p, [0.9, 0.5])
