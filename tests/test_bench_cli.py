"""`python -m glmap_tools.bench NAME`: the dispatcher's errors."""

from __future__ import annotations

import pytest

from glmap_tools.bench.__main__ import main


def test_a_benchmark_given_bad_input_says_what_is_wrong_without_a_traceback(capsys, tmp_path):
    argv = ["nav", "--skip-speed", "--table", "--episodes-per-scene", "0", "--out", str(tmp_path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("bench nav: error: episodes_per_scene=0 must be a positive integer")
    assert "Traceback" not in err and list(tmp_path.iterdir()) == []


def test_an_unknown_benchmark_gets_the_closest_name(capsys):
    assert main(["estimater"]) == 2
    assert "estimator" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["estimator", "--repeats", "0"], "argument --repeats: 0 is not in 1..10000"),
        (["render", "--counts", "-5"], "argument --counts: -5 is not in 1..10000000"),
        (["render", "--sizes", "abc"], "argument --sizes: 'abc' is not WIDTHxHEIGHT"),
        (["startup", "--timeout", "-1"], "argument --timeout: -1 s is not in (0, 3600]"),
        (["startup", "--runs", "x"], "argument --runs: 'x' is not a whole number"),
        (["search", "--queries", "nowhere.jsonl"], "argument --queries: 'nowhere.jsonl' is not"),
        (["sim", "--steps", "-1"], "argument --steps: -1 is not in 1..100000"),
        (["lock", "--objects", "-1"], "argument --objects: -1 is not in 1..64"),
        (["views", "--chairs", "-2"], "argument --chairs: -2 is not in 1..200"),
        (["percall", "--size", "0x10"], "argument --size: '0x10' is not WIDTHxHEIGHT"),
    ],
)
def test_an_option_out_of_range_is_a_usage_error_before_anything_runs(capsys, argv, said):
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err
