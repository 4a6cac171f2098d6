"""glmap eval compare: two result folders side by side, paired on common episodes."""

import json

import pytest

from glmap_tools import cli
from glmap_tools.errors import InvalidInputError
from glmap_tools.eval.compare import compare


def _folder(root, prompts, outcomes, tokens):
    (root / "episodes" / "llm-tools").mkdir(parents=True)
    (root / "eval.json").write_text(
        json.dumps({"config": {"task": "objectnav", "prompts": prompts}})
    )
    for i, ok in enumerate(outcomes):
        record = {
            "agent": "llm-tools",
            "episode_id": f"tune/objectnav/s00-{i:03d}",
            "success": ok,
            "spl": 0.5 * ok,
            "tool_calls": 10 + i,
            "tokens": tokens,
        }
        (root / "episodes" / "llm-tools" / f"e{i}.json").write_text(json.dumps(record))
    return root


def test_two_prompt_runs_compare_on_their_common_episodes(tmp_path):
    a = _folder(tmp_path / "a", "aaaa", [1, 0, 0, 1], 1000)
    b = _folder(tmp_path / "b", "bbbb", [1, 1, 1, 1, 0], 1500)
    table = compare(a, b, resamples=200)
    assert "prompts ('aaaa' vs 'bbbb')" in table
    row = next(line for line in table.splitlines() if line.startswith("| llm-tools"))
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert cells[1] == "4"  # the fifth episode of B has no partner in A
    assert cells[2].startswith("0.500") and cells[3].startswith("1.000")
    assert cells[4].startswith("0.500")  # paired SR difference B - A
    assert cells[-2:] == ["1000", "1500"]


def test_a_folder_that_is_not_a_results_folder_is_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="no eval.json"):
        compare(tmp_path, tmp_path)


def test_the_cli_runs_compare(tmp_path, capsys):
    a = _folder(tmp_path / "a", "x", [1, 0], 0)
    b = _folder(tmp_path / "b", "y", [1, 1], 0)
    assert cli.main(["eval", "compare", str(a), str(b), "--resamples", "100"]) == 0
    assert "| llm-tools | 2 |" in capsys.readouterr().out
