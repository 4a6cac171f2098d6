"""Build the labelled search query set `glmap_tools/data/search_queries.jsonl`.

Run: ``python -m glmap_tools.worlds.search_queries [--out PATH]`` (deterministic).

Each line is one query over one generated apartment (`generate_apartment(scene)`) with its
known answers, the layout ids of the objects (kind 'instance') or regions (kind 'region')
that it asks for; an empty list means nothing in that scene answers it (the map should say
"no match"). Concepts below are written as people ask: by name, by synonym, by what a thing
is for ("somewhere to sleep"), by colour. Every concept has tuning wordings and different
held-out wordings; tuning scenes and held-out scenes are different apartments too, so the
held-out half shares neither a sentence nor a scene with the half used to tune the ranking.
The answers are resolved from the layout's ground truth (category, and a word of the
description where the category alone is ambiguous, e.g. a kitchen sink).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from glmap_tools.sim.layout import Layout
from glmap_tools.worlds.generator import generate_apartment

TUNE_SCENES = (0, 1, 2, 3, 4, 5)
HELD_OUT_SCENES = (6, 7, 8, 9, 10, 11)


@dataclass(frozen=True)
class Concept:
    """What a group of wordings asks for, and how to find its answers in a layout.

    Attributes:
        kind: 'instance' (answers are objects) or 'region'.
        categories: object categories (instances) or region names (regions) that answer.
        tune: wordings for the tuning half.
        held_out: other wordings for the held-out half.
        phrasing: 'name', 'synonym', 'affordance' or 'absent'.
        contains: a word the answer's description must hold ('' = any).
    """

    kind: str
    categories: tuple[str, ...]
    tune: tuple[str, ...]
    held_out: tuple[str, ...]
    phrasing: str
    contains: str = ""


def _i(cats: str, tune: str, held: str, phrasing: str, contains: str = "") -> Concept:
    return Concept(
        "instance", tuple(cats.split(",")), tuple(tune.split(";")), tuple(held.split(";")),
        phrasing, contains,
    )  # fmt: skip


def _r(names: str, tune: str, held: str, contains: str = "") -> Concept:
    return Concept(
        "region", tuple(names.split(",")), tuple(tune.split(";")), tuple(held.split(";")),
        "affordance", contains,
    )  # fmt: skip


CONCEPTS = (
    _i(
        "bed",
        "somewhere to sleep;a place to lie down at night",
        "where can I take a nap;something to sleep on",
        "affordance",
    ),
    _i(
        "sofa,chair,armchair",
        "something to sit on;a seat",
        "somewhere to sit down;where can I sit",
        "affordance",
    ),
    _i(
        "stove",
        "something to cook on;where to fry an egg",
        "somewhere to cook dinner;a cooker with hot plates",
        "affordance",
    ),
    _i(
        "refrigerator",
        "the fridge;somewhere to keep milk cold",
        "where do I store cold food;a freezer",
        "synonym",
    ),
    _i("coffee machine", "something to make coffee", "an espresso maker", "affordance"),
    _i("toaster", "something to toast bread", "a device for making toast", "affordance"),
    _i(
        "tv",
        "the television;something to watch shows on",
        "a tv screen;where can I watch a film",
        "synonym",
    ),
    _i(
        "trash can",
        "a rubbish bin;where do I throw away garbage",
        "a waste basket;somewhere to dispose of litter",
        "synonym",
    ),
    _i("toilet", "a toilet bowl", "the lavatory", "name"),
    _i("bathtub", "somewhere to take a bath", "a tub to soak in", "affordance"),
    _i("sink", "somewhere to wash my hands", "a basin with a tap", "affordance"),
    _i(
        "sink", "where to wash the dishes", "where can I do the washing up", "affordance", "kitchen"
    ),
    _i("wardrobe", "where to hang my coat", "a closet for clothes", "affordance"),
    _i("dresser", "a chest of drawers", "a bureau with drawers", "synonym"),
    _i("washing machine", "something to wash clothes", "a washer for laundry", "affordance"),
    _i("plant", "a houseplant", "something green that needs watering", "synonym"),
    _i("picture", "a painting on the wall", "wall art", "synonym"),
    _i("table lamp,floor lamp", "a light to read by", "a lamp", "affordance"),
    _i("nightstand", "a bedside table", "a small table next to the bed", "synonym"),
    _i("bookcase", "somewhere to put my books", "a bookshelf", "affordance"),
    _i("desk", "somewhere to work on my laptop", "a writing desk", "affordance"),
    _i("monitor", "a computer screen", "a display for the computer", "synonym"),
    _i("table", "somewhere to eat dinner", "a dining table", "affordance"),
    _i("coffee table", "a low table in front of the sofa", "the coffee table", "name"),
    _i("rug", "a carpet on the floor", "a mat", "synonym"),
    _i("kitchen cabinet", "a cupboard in the kitchen", "where to keep plates and pots", "synonym"),
    _i("tv stand", "the cabinet the tv stands on", "a media console", "synonym"),
    _i("piano", "a piano", "a grand piano", "absent"),
    _i("bicycle", "a bicycle", "a bike", "absent"),
    _i("fireplace", "a fireplace", "somewhere to light a fire", "absent"),
    _i("treadmill", "a treadmill", "something to run on indoors", "absent"),
    _i("aquarium", "an aquarium with fish", "a fish tank", "absent"),
    _r(
        "sleeping area",
        "somewhere to sleep;the bedroom corner",
        "where to rest at night;the bed area",
    ),
    _r(
        "cooking area",
        "where to prepare food;the kitchen counter",
        "the kitchen area;where meals are cooked",
    ),
    _r(
        "seating area",
        "where to relax and watch tv;the lounge",
        "somewhere to unwind in front of the television;the living room sofa corner",
    ),
    _r("washing area", "where to brush my teeth", "the bathroom area"),
    _r("storage area", "where clothes are kept", "somewhere to store my shirts", "clothes"),
    _r("dining area,breakfast nook", "where to eat", "a place for family meals"),
    _r("work area", "where to work at a computer", "a home office corner"),
    _r("garage", "the garage", "where the car is parked"),
    _r("gym", "a home gym", "somewhere to lift weights"),
)

# Colour queries: tuning and held-out templates over objects whose colour tells them apart.
COLOUR_TEMPLATES = {"tune": "the {color} {category}", "held_out": "a {category} that is {color}"}
COLOUR_QUERIES_PER_SCENE = 3


def default_queries_path() -> Path:
    """Path of the bundled query set."""
    return Path(str(resources.files("glmap_tools") / "data" / "search_queries.jsonl"))


def _answers(layout: Layout, concept: Concept) -> list[int]:
    if concept.kind == "instance":
        return [
            o.id
            for o in layout.objects
            if o.category in concept.categories and concept.contains in o.text
        ]
    return [
        r.id
        for r in layout.regions
        if r.name in concept.categories and concept.contains in r.description
    ]


def _colour_queries(layout: Layout, template: str) -> list[tuple[str, list[int]]]:
    """Objects whose colour is unique among two or more of their category in the scene."""
    by_cat: dict[str, list] = {}
    for o in layout.objects:
        by_cat.setdefault(o.category, []).append(o)
    out = []
    for category, objs in sorted(by_cat.items()):
        colours = [o.attributes.get("color") for o in objs]
        for o, colour in zip(objs, colours, strict=True):
            if len(objs) >= 2 and colour and colours.count(colour) == 1:
                out.append((template.format(color=colour, category=category), [o.id]))
    return out


def build(scenes_by_split: dict[str, Sequence[int]] | None = None) -> list[dict]:
    """All query rows, tuning scenes first; see the module docstring."""
    scenes_by_split = scenes_by_split or {"tune": TUNE_SCENES, "held_out": HELD_OUT_SCENES}
    rows: list[dict] = []
    for split, scenes in scenes_by_split.items():
        for n, scene in enumerate(scenes):
            layout = generate_apartment(scene)
            for c, concept in enumerate(CONCEPTS):
                wordings = concept.tune if split == "tune" else concept.held_out
                answers = _answers(layout, concept)
                # Keep some concepts this scene lacks as queries with no answer.
                absent_here = not answers and concept.phrasing != "absent"
                if absent_here and concept.kind == "instance" and (n + c) % 4:
                    continue
                if not answers and concept.kind == "region" and (n + c) % 3:
                    continue
                phrasing = concept.phrasing if answers else "absent"
                query = wordings[(n + c) % len(wordings)]
                rows.append(_row(split, scene, concept.kind, query, phrasing, answers))
            colour = _colour_queries(layout, COLOUR_TEMPLATES[split])
            step = max(1, len(colour) // COLOUR_QUERIES_PER_SCENE)
            for query, answers in colour[::step][:COLOUR_QUERIES_PER_SCENE]:
                rows.append(_row(split, scene, "instance", query, "colour", answers))
    for k, row in enumerate(rows, start=1):
        row["id"] = f"q{k:03d}"
    return rows


def _row(split: str, scene: int, kind: str, query: str, phrasing: str, answers: list[int]) -> dict:
    return {
        "split": split,
        "scene": scene,
        "kind": kind,
        "query": query,
        "phrasing": phrasing,
        "answers": answers,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Write the query set as JSON lines."""
    parser = argparse.ArgumentParser(
        prog="python -m glmap_tools.worlds.search_queries",
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--out", type=Path, default=default_queries_path(), help="file to write")
    args = parser.parse_args(argv)
    rows = build()
    lines = [json.dumps({"id": r.pop("id"), **r}) for r in rows]
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    splits = {s: sum(r["split"] == s for r in rows) for s in ("tune", "held_out")}
    print(f"wrote {len(rows)} queries to {args.out}: {splits}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
