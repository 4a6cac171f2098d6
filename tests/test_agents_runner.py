"""agents.runner through in-memory MCP sessions: traces, reports, replay, baselines, bad input."""

from __future__ import annotations

import json
import os
import re

import pytest

from agents.runner import AGENTS, EpisodeResult, main, open_session, run_episode
from agents.trace import ToolCallError
from glmap_tools.errors import InvalidInputError
from glmap_tools.worlds.splits import load_split
from tests.test_server_fixtures import config

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
pytestmark = pytest.mark.anyio
EPISODE = load_split("tune", "objectnav")[0].episode_id


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def calls(out) -> list[dict]:  # type: ignore[no-untyped-def, type-arg]
    lines = (out / "trace.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines]


async def test_a_seeded_episode_replays_identically(tmp_path):
    traces = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        async with open_session(config(tmp_path)) as session:
            result = await run_episode(
                session, EPISODE, "glmap", seed=7, out_dir=out, max_steps=10, image_every=0
            )
        assert result.steps == 10 or result.success or result.steps < 10
        traces.append([{k: v for k, v in c.items() if k != "ms"} for c in calls(out)])
    assert traces[0] == traces[1]
    assert [c["tool"] for c in traces[0]][:2] == ["sim_reset", "nav_step"]


async def test_the_random_agent_acts_uniformly_and_ends_only_at_the_step_limit(tmp_path):
    async with open_session(config(tmp_path)) as session:
        result = await run_episode(
            session, EPISODE, "random", seed=1, out_dir=tmp_path / "r", max_steps=9
        )
    assert isinstance(result, EpisodeResult)
    assert result.steps == 9 and not result.success and result.tool_calls == 10
    actions = [c["arguments"]["action"] for c in calls(tmp_path / "r")[1:]]
    assert set(actions) <= {"move_forward", "turn_left", "turn_right"} and len(set(actions)) > 1
    final = json.loads(calls(tmp_path / "r")[-1]["texts"][0])
    assert final["status"] == "out of steps"


async def test_a_run_writes_a_trace_of_every_call_and_a_report_with_value_maps(tmp_path):
    out = tmp_path / "episode"
    async with open_session(config(tmp_path)) as session:
        result = await run_episode(
            session, EPISODE, "glmap-instance", seed=0, out_dir=out, max_steps=6, image_every=2
        )
    trace = calls(out)
    assert len(trace) == result.tool_calls and result.agent == "glmap-instance"
    assert all(c["ms"] > 0 for c in trace)
    md = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    images = re.findall(r"\]\((images/[^)]+)\)", md)
    assert any(i.endswith("_nav_step_2.png") for i in images)  # value map, frontiers, path
    assert any(i.endswith("_nav_step_1.jpg") for i in images)  # egocentric frame
    for img in images:
        assert (out / img).stat().st_size > 500 and f"src='{img}'" in page
    assert "| step | action |" in md and json.loads((out / "result.json").read_text())["seed"] == 0


async def test_unknown_agents_and_episodes_are_refused_with_the_closest_name(tmp_path, capsys):
    async with open_session(config(tmp_path)) as session:
        with pytest.raises(InvalidInputError, match="Did you mean 'glmap'"):
            await run_episode(session, EPISODE, "glmpa", seed=0)
        with pytest.raises(ToolCallError, match="Did you mean"):
            await run_episode(session, EPISODE[:-1], "random", seed=0)
    assert main([EPISODE, "--agent", "frontiers"]) == 2
    assert "Did you mean 'frontier'" in capsys.readouterr().err
    assert AGENTS == (
        "glmap",
        "glmap-instance",
        "glmap-region",
        "egocentric",
        "frontier",
        "random",
        "llm-tools",
        "glmap+oracle-room",
        "glmap+wrong-room",
        "glmap+embedding",
        "glmap+recorded",
    )


def test_a_refused_episode_is_one_error_line_without_a_traceback(tmp_path, capsys):
    # the server's refusal came out of the task group as an ExceptionGroup traceback
    argv = [EPISODE, "--embedder", "hashing", "--out", str(tmp_path / "out"), "--seed", "-1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "error: sim_reset failed: sim_reset: invalid arguments; seed:" in err
    assert "Traceback" not in err and "ExceptionGroup" not in err


def test_the_sqa_and_llm_agents_print_a_refusal_as_one_line(tmp_path, capsys):
    from agents import llm_agent, sqa

    assert (
        sqa.main(["--situation", "on the bed", "--question", "what?", "--embedder", "hashing"]) == 2
    )
    said = capsys.readouterr().err
    assert "error: locate_situation failed:" in said and "the map is empty" in said
    argv = [EPISODE[:-1], "--embedder", "hashing", "--out", str(tmp_path), "--max-turns", "1"]
    assert llm_agent.main(argv) == 2  # refused by the server before any model call
    said = capsys.readouterr().err
    assert "error: sim_reset failed:" in said and "Did you mean" in said
    assert "Traceback" not in said


def test_the_sqa_and_llm_agents_refuse_a_bad_prompts_folder_before_starting(tmp_path, capsys):
    from agents import llm_agent, sqa

    (tmp_path / "tool_agent_system.txt").write_text('Play {task} in {max_turns}; reply {"a": 1}')
    for agent_main, argv in (
        (llm_agent.main, [EPISODE, "--prompts", str(tmp_path)]),
        (sqa.main, ["--situation", "on the bed", "--question", "?", "--prompts", str(tmp_path)]),
        (sqa.main, ["--situation", "on the bed", "--question", "?", "--prompts", "nowhere"]),
    ):
        with pytest.raises(SystemExit) as stopped:
            agent_main(argv)
        assert stopped.value.code == 2
        said = capsys.readouterr().err.strip().splitlines()[-1]
        assert "error: prompt file" in said or "'nowhere' is not a folder" in said
        assert "Traceback" not in said


async def test_an_instnav_episode_runs_the_instnav_agent_on_a_description(tmp_path):
    episode = load_split("tune", "instnav")[0]
    out = tmp_path / "inst"
    async with open_session(config(tmp_path)) as session:
        result = await run_episode(
            session, episode.episode_id, "egocentric", seed=0, out_dir=out, max_steps=3
        )
    start = json.loads(calls(out)[0]["texts"][0])
    assert start["task"] == "instnav" and start["goal"] == episode.episode.goal_text
    assert result.steps <= 3 and result.tool_calls == 1 + result.steps
    assert all(c["arguments"]["policy"] == "egocentric" for c in calls(out)[1:])


@pytest.mark.slow
async def test_an_agent_can_drive_a_server_started_as_a_stdio_command(tmp_path):
    import shlex
    import sys

    command = shlex.join(
        [sys.executable, "-m", "glmap_tools.server", "--embedder", "hashing", "--no-warm-up"]
        + ["--maps-dir", str(tmp_path / "maps")]
    )
    async with open_session(server_command=command) as session:
        result = await run_episode(session, EPISODE, "random", seed=2, max_steps=3)
    assert result.steps == 3 and result.tool_calls == 4
