"""`python -m glmap_tools.bench NAME`: the dispatcher's errors."""

from __future__ import annotations

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
