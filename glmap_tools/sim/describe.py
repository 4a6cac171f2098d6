"""Natural-language descriptions of objects and regions, built from their attributes."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

NUMBER_WORDS = [
    "no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
    "eleven", "twelve",
]  # fmt: skip

PLURALS = {
    "shelf": "shelves",
    "bookcase": "bookcases",
    "books": "books",
    "box": "boxes",
    "couch": "couches",
    "bench": "benches",
}

PLURAL_NOUNS = {"books"}

# Templates for categories whose attributes read better in a fixed phrase.
TEMPLATES = {
    "bed": "{size} bed with a {color} cover",
    "plant": "{size} potted plant in a {color} pot",
    "floor lamp": "floor lamp with a {color} shade",
    "table lamp": "table lamp with a {color} shade",
    "picture": "framed picture in {color} tones",
    "books": "stack of {color} books",
    "rug": "{shape} {color} rug",
    "sink": "{color} {style} sink",
    "tv": "{color} {style} tv",
    "chair": "{color} {material} chair",
}
ORDER = ("size", "color", "material", "shape", "style")


def number_word(n: int) -> str:
    return NUMBER_WORDS[n] if 0 <= n < len(NUMBER_WORDS) else str(n)


def plural(category: str) -> str:
    if category in PLURALS:
        return PLURALS[category]
    last = category.split()[-1]
    if last in PLURALS:
        return category[: -len(last)] + PLURALS[last]
    return category + ("es" if category.endswith(("s", "sh", "ch")) else "s")


def with_article(phrase: str) -> str:
    return ("an " if phrase[:1].lower() in "aeiou" else "a ") + phrase


def object_phrase(category: str, attributes: Mapping[str, str]) -> str:
    """The noun phrase without article, e.g. "blue metal chair" or "double bed with ..."."""
    template = TEMPLATES.get(category)
    if template is not None:
        keys = [k for k in ORDER if "{" + k + "}" in template]
        if all(attributes.get(k) for k in keys):
            text = template.format(**{k: attributes[k] for k in keys})
            return re.sub(r"\ba ([aeiou])", r"an \1", text)
    words = [attributes[k] for k in ORDER if attributes.get(k)]
    material = attributes.get("material")
    if material in ("wood", "oak", "walnut") and "color" not in attributes:
        words = [w if w != material else ("wooden" if w == "wood" else w) for w in words]
    return " ".join([*words, category])


def object_description(category: str, attributes: Mapping[str, str]) -> str:
    """E.g. "a blue metal chair", "a double bed with a green cover"."""
    return with_article(object_phrase(category, attributes))


def count_phrase(categories: Sequence[str]) -> str:
    """E.g. ["table", "chair", "chair"] -> "a table and two chairs"."""
    counts: dict[str, int] = {}
    for c in categories:
        counts[c] = counts.get(c, 0) + 1
    parts = [
        ("some " + c if c in PLURAL_NOUNS else with_article(c))
        if n == 1
        else f"{number_word(n)} {'stacks of ' + c if c in PLURAL_NOUNS else plural(c)}"
        for c, n in counts.items()
    ]
    if len(parts) == 1:
        return parts[0]
    return ", ".join(parts[:-1]) + " and " + parts[-1]


def region_description(name: str, purpose: str, categories: Sequence[str]) -> str:
    """E.g. "dining area: a table and four chairs, for eating meals"."""
    return f"{name}: {count_phrase(categories)}, {purpose}"
