"""Bootstrap intervals, paired differences and the Markdown table of `glmap eval`."""

from __future__ import annotations

import numpy as np
import pytest

from glmap_tools.errors import InvalidInputError
from glmap_tools.eval import (
    bootstrap_mean,
    bootstrap_mean_reference,
    markdown,
    paired_difference,
    summarize,
)


@pytest.mark.parametrize("n", [1, 7, 60])
@pytest.mark.parametrize("seed", [0, 3])
def test_the_fast_bootstrap_equals_its_slow_reference(n: int, seed: int) -> None:
    values = np.random.default_rng(100 + n).normal(size=n)
    for resamples in (1, 300, 700):  # 700 spans several chunks of the fast path
        fast = bootstrap_mean(values, resamples=resamples, seed=seed, confidence=0.9)
        slow = bootstrap_mean_reference(values, resamples=resamples, seed=seed, confidence=0.9)
        assert fast.n == slow.n == n
        np.testing.assert_allclose(
            [fast.mean, fast.low, fast.high], [slow.mean, slow.low, slow.high], atol=1e-12
        )


def test_three_successes_in_ten_have_the_hand_computed_interval() -> None:
    # A resample's success rate is Binomial(10, 0.3) / 10. Its CDF: P(0) = 0.0282 > 0.025, so
    # the 2.5% quantile is 0.0; P(<=0.5) = 0.9527 < 0.975 <= P(<=0.6) = 0.9894, so the
    # 97.5% quantile is 0.6. The 95% interval of SR = 0.3 is therefore [0.0, 0.6].
    values = np.array([1, 0, 0, 1, 0, 0, 0, 1, 0, 0], dtype=float)
    iv = bootstrap_mean(values, resamples=50_000, seed=1)
    assert iv.mean == pytest.approx(0.3)
    assert (iv.low, iv.high) == (pytest.approx(0.0), pytest.approx(0.6))


def test_identical_values_have_an_interval_of_zero_width() -> None:
    iv = bootstrap_mean(np.full(9, 0.42))
    assert iv.low == pytest.approx(0.42) and iv.high == pytest.approx(0.42)


def test_the_same_seed_gives_the_same_interval_and_another_seed_another() -> None:
    values = np.random.default_rng(5).random(40)
    assert bootstrap_mean(values, seed=2) == bootstrap_mean(values, seed=2)
    assert bootstrap_mean(values, seed=2) != bootstrap_mean(values, seed=3)


def test_a_paired_difference_moves_both_agents_values_together() -> None:
    # Agent a is exactly 0.1 better on every episode, though episodes vary widely: the paired
    # interval is [0.1, 0.1], while each agent's own interval is wide and they overlap.
    b = np.random.default_rng(0).random(30)
    a = b + 0.1
    diff = paired_difference(a, b)
    assert diff.mean == pytest.approx(0.1)
    assert (diff.low, diff.high) == (pytest.approx(0.1), pytest.approx(0.1))
    assert not bootstrap_mean(a).apart_from(bootstrap_mean(b))


def test_paired_values_over_different_episodes_are_refused() -> None:
    with pytest.raises(InvalidInputError, match="same episodes"):
        paired_difference(np.zeros(3), np.zeros(4))


@pytest.mark.parametrize(
    ("values", "kw", "message"),
    [
        ([], {}, "non-empty"),
        ([0.5, float("nan")], {}, "NaN or inf"),
        ([0.5, 1.0], {"resamples": 0}, "resamples=0"),
        ([0.5, 1.0], {"confidence": 1.5}, "confidence=1.5"),
    ],
)
def test_bad_bootstrap_inputs_name_the_value_and_the_fix(
    values: list[float], kw: dict[str, float], message: str
) -> None:
    with pytest.raises(InvalidInputError, match=message):
        bootstrap_mean(np.array(values), **kw)  # type: ignore[arg-type]


def _record(success: bool, spl: float, dtg: float | None, steps: int) -> dict[str, object]:
    return {
        "success": success,
        "spl": spl,
        "distance_to_goal": dtg,
        "steps": steps,
        "tool_calls": steps + 1,
    }


def test_the_table_shows_each_agent_with_intervals_and_the_paired_rows() -> None:
    records = {
        "glmap": {f"e{i}": _record(True, 0.5, 0.4, 20) for i in range(4)},
        "random": {
            "e0": _record(True, 0.25, 0.8, 500),
            "e1": _record(False, 0.0, None, 500),  # ended where the goal is unreachable
            "e2": _record(False, 0.0, 3.0, 500),
            "e3": _record(False, 0.0, 5.0, 500),
        },
    }
    summary = summarize(records, ["glmap", "random"], resamples=500)
    text = markdown(summary)
    lines = text.splitlines()
    assert lines[0].startswith("| Agent | Episodes | SR (%) | SPL (%) | Dist. to goal (m) |")
    assert "| glmap | 4 | 100.0 [100.0, 100.0] | 50.0 [50.0, 50.0] | 0.40 [0.40, 0.40] |" in text
    sr = summary.rows["random"]["success"]
    assert (sr.mean, sr.n) == (25.0, 4)
    assert f"| random | 4 | 25.0 [{sr.low:.1f}, {sr.high:.1f}] |" in text
    dtg = summary.rows["random"]["distance_to_goal"]
    assert dtg.n == 3 and dtg.mean == pytest.approx((0.8 + 3.0 + 5.0) / 3)
    diff = summary.paired[("glmap", "random")]["success"]
    assert diff.mean == pytest.approx(75.0) and diff.n == 4
    assert f"| glmap − random | 4 | +75.0 [{diff.low:+.1f}, {diff.high:+.1f}] |" in text
    assert "500 resamples, seed 0" in text


def test_the_paired_rows_use_only_the_episodes_both_agents_finished() -> None:
    records = {
        "a": {"e0": _record(True, 1.0, 0.0, 5), "e1": _record(True, 1.0, 0.0, 5)},
        "b": {"e1": _record(False, 0.0, 2.0, 9), "e2": _record(False, 0.0, 2.0, 9)},
    }
    summary = summarize(records, ["a", "b"], resamples=200)
    assert summary.paired[("a", "b")]["success"].n == 1
    assert summary.to_json()["paired"][0]["success"]["mean"] == pytest.approx(100.0)


def test_the_table_does_not_depend_on_the_order_results_were_read_in() -> None:
    # SPL values for which the bootstrap of the reversed order gives another interval.
    spl = np.random.default_rng(1).random(20)
    rev = spl[::-1]
    assert bootstrap_mean(spl, resamples=300) != bootstrap_mean(rev, resamples=300)
    episodes = {f"e{i:02d}": _record(True, float(v), 1.0, 9) for i, v in enumerate(spl)}
    shuffled = dict(reversed(list(episodes.items())))
    a = summarize({"x": episodes}, ["x"], resamples=300)
    b = summarize({"x": shuffled}, ["x"], resamples=300)
    assert a.rows["x"]["spl"] == b.rows["x"]["spl"]


def test_episodes_needed_for_a_paired_difference_follow_the_discordance() -> None:
    from glmap_tools.eval.stats import episodes_needed

    # 27% of episodes disagree, +6 points: (1.96 + 0.84)^2 (0.27 - 0.0036) / 0.0036 = 581.
    assert episodes_needed(0.27, 0.06) == 581
    assert episodes_needed(0.27, -0.06) == 581
    assert episodes_needed(0.10, 0.06) < episodes_needed(0.27, 0.06)  # less chaos, fewer
    assert episodes_needed(0.27, 0.06, power=0.5) == 285  # the interval just excludes 0
    with pytest.raises(InvalidInputError, match="difference=0.3 must be"):
        episodes_needed(0.27, 0.3)
