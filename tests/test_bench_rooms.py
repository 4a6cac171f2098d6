"""bench rooms: the best unit score inside and outside the goal's room, per episode."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from glmap_tools.bench.report import Report
from glmap_tools.bench.rooms import RoomScores, episode_room_scores, main, room_table
from glmap_tools.errors import InvalidInputError
from glmap_tools.nav.scorers import UnitText
from glmap_tools.worlds.splits import bench_layout, load_split


class WordScorer:
    """f_S that gives 1 to texts containing a word and 0.1 to the rest."""

    def __init__(self, word: str) -> None:
        self.word = word

    def score(self, goal: str, units: Sequence[UnitText]) -> np.ndarray:
        return np.array([1.0 if self.word in u.text else 0.1 for u in units])


def test_room_scores_split_units_by_the_goal_objects_rooms_and_leave_the_goal_out() -> None:
    be = load_split("tune", "objectnav")[0]
    layout = bench_layout(be.layout_path)
    goal_ids = be.episode.goal_object_ids
    goal_rooms = {o.room for o in layout.objects if o.id in goal_ids}
    goal_text = next(o.description for o in layout.objects if o.id in goal_ids)
    # Only objects with the goal's own description score 1; the goal objects are not scored.
    twins = {o.room for o in layout.objects if o.description == goal_text and o.id not in goal_ids}
    scores = episode_room_scores(WordScorer(goal_text), "x", layout, goal_ids)["instance"]
    assert scores.same == (1.0 if twins & goal_rooms else 0.1)
    assert scores.other == (1.0 if twins - goal_rooms else 0.1)

    region = next(r for r in layout.regions if r.room in goal_rooms and r.description)
    word = region.description.split(":")[0]
    scores = episode_room_scores(WordScorer(word), "x", layout, goal_ids)["region"]
    elsewhere = [r for r in layout.regions if r.room not in goal_rooms and word in r.description]
    assert scores.same == 1.0 and scores.other == (1.0 if elsewhere else 0.1)
    regions = [r for r in layout.regions if r.description]
    share = sum(r.room in goal_rooms for r in regions) / len(regions)
    assert scores.chance == pytest.approx(share)


def test_room_scores_refuse_goal_ids_the_layout_does_not_hold() -> None:
    be = load_split("tune", "objectnav")[0]
    with pytest.raises(InvalidInputError, match="are not in layout .*regenerate the split"):
        episode_room_scores(WordScorer("a"), "x", bench_layout(be.layout_path), (99999,))


def test_room_table_counts_a_tie_as_a_miss() -> None:
    rows = [
        {"region": RoomScores(0.5, 0.2), "instance": RoomScores(0.3, 0.3)},
        {"region": RoomScores(0.4, 0.45), "instance": RoomScores(0.6, 0.1)},
    ]
    ranking = room_table(rows, Report("t", quiet=True))
    assert ranking == {"region": 0.5, "instance": 0.5}


def test_the_bundled_embedder_ranks_the_goals_room_first_by_regions_on_the_tune_split(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "100 episodes, 4 scenes" in out
    line = next(x for x in out.splitlines() if x.startswith("region units: goal's room"))
    assert line.endswith("MET"), line  # 0.91 when measured in session 11


def test_the_llm_scorer_without_a_server_is_one_clear_line_and_status_2(
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = ["--scorer", "llm", "--ollama-host", "http://127.0.0.1:9", "--llm-timeout", "5"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("bench rooms: Ollama is not reachable at http://127.0.0.1:9")
    assert "Traceback" not in err
