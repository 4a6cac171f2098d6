"""'Did you mean' only when close (issue 40): a scan label of another thing gets no
suggestion that would relabel the object, a typo still gets one."""

from __future__ import annotations

import pytest

from glmap_tools.errors import closest, did_you_mean

# Catalog-like names the scan labels below were suggested against before.
CHOICES = ["plant", "cabinet", "washer", "couch", "chair", "poster", "table", "sofa", "4"]


@pytest.mark.parametrize(
    "label", ["blanket", "candle", "vase", "clock", "camera", "pot", "rug", "lamp shade"]
)
def test_a_label_of_another_thing_gets_no_suggestion(label: str) -> None:
    assert did_you_mean(label, CHOICES + ["mug"]) == ""


@pytest.mark.parametrize(
    ("typo", "meant"),
    [
        ("chiar", "chair"),
        ("tabel", "table"),
        ("sofaa", "sofa"),
        ("Sofa", "sofa"),
        ("cabinett", "cabinet"),
        ("posters", "poster"),
        ("40", "4"),
        ("plnt", "plant"),
    ],
)
def test_a_typo_still_gets_the_closest_name(typo: str, meant: str) -> None:
    assert closest(typo, CHOICES) == meant
    assert did_you_mean(typo, CHOICES) == f" Did you mean {meant!r}?"
