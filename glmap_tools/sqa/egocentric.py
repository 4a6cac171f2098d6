"""Answers that turn on where things lie around me: clock hours, which side, turning,
looking up or down, counts on an object and divisibility.

Bearings are degrees from straight ahead (+ = left), distances metres, heights metres
above the floor (z = 0). A unit named with a place ("the chair at my two o'clock", "the
lamp on my left") is the nearest unit of its label in that sector.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence

from glmap_tools.sqa.records import MapAnswer
from glmap_tools.sqa.situation_words import NUMBER_WORDS
from glmap_tools.sqa.surroundings import Nearby, Surroundings
from glmap_tools.sqa.wording import EGO, HOURS

Match = Callable[[str, Sequence[str]], "str | None"]
SIDE_HALF = 45.0  # deg: half a side sector (left is 45..135)
HOUR_HALF = 20.0  # deg either side of a clock hour
FOV = 120.0  # deg: what one sees without turning the head far
EYE = 1.5  # m: eye height of a standing person
AROUND = 4.0  # m: "around me", "in this room"
ON_RISE = 0.1  # m: a unit on another starts at least this far above the other's bottom
BESIDE = 1.5  # m between centres: "what is next to the bed?"


def wrap(deg: float) -> float:
    """An angle in degrees wrapped to (-180, 180]."""
    return math.degrees(math.remainder(math.radians(deg), math.tau))


def hour_bearing(hour: str) -> float:
    """The bearing of a clock hour (12 ahead, 3 right, 9 left): '3' -> -90."""
    h = int(hour) if hour.isdigit() else HOURS.index(hour) + 1
    return wrap(-30.0 * (h % 12))


def sector_of(parts: dict[str, str]) -> tuple[float, float] | None:
    """(centre, half-width) in degrees of the place a question names, None for around."""
    if "view" in parts:  # "how many chairs can I see?"
        return 0.0, FOV / 2
    if "hour" in parts:
        return hour_bearing(parts["hour"]), HOUR_HALF
    if "side" in parts:
        return (90.0 if parts["side"] == "left" else -90.0), SIDE_HALF
    if "behind" in parts:
        return 180.0, SIDE_HALF
    if "front" in parts:
        return 0.0, SIDE_HALF
    return None


def in_sector(n: Nearby, sector: tuple[float, float] | None) -> bool:
    if sector is None:
        return n.distance <= AROUND
    return abs(wrap(n.bearing - sector[0])) <= sector[1]


def split_ego(phrase: str) -> tuple[str, tuple[float, float] | None]:
    """('chair', (-60, 20)) from 'chair at my two o'clock'; (phrase, None) without a place."""
    m = re.search(r"\s+" + EGO + r"\s*$", phrase)
    if not m:
        return phrase, None
    parts = {k: v for k, v in m.groupdict().items() if v}
    return phrase[: m.start()], sector_of(parts)


def pick(near: Sequence[Nearby], label: str | None, phrase: str) -> Nearby | None:
    """The nearest unit of the label in the phrase's place, the one whose description
    shares most of the phrase's other words first ("the blue chair on my left")."""
    words, sector = split_ego(phrase)
    cands = [n for n in near if n.label == label and (sector is None or in_sector(n, sector))]
    if not cands:
        return None
    extra = set(re.findall(r"[a-z]+", words.lower())) - set((label or "").split())

    def shared(n: Nearby) -> int:
        return len(extra & set(re.findall(r"[a-z]+", n.text.lower())))

    best = max(shared(n) for n in cands)
    return next(n for n in cands if shared(n) == best)


def _number(word: str) -> int | None:
    if word.isdigit():
        return int(word)
    return NUMBER_WORDS.index(word) if word in NUMBER_WORDS else None


def clock(parts: dict[str, str], near: Sequence[Nearby]) -> MapAnswer:
    """The nearest unit within HOUR_HALF degrees of the hour asked."""
    centre = hour_bearing(parts["hour"])
    hits = [n for n in near if abs(wrap(n.bearing - centre)) <= HOUR_HALF]
    if not hits:
        return MapAnswer(
            "nothing", "clock", True, f"nothing within {HOUR_HALF:.0f} deg of {centre:.0f} deg"
        )
    n = hits[0]
    return MapAnswer(
        n.label, "clock", True, f"unit {n.unit_id} at {n.bearing:.0f} deg, {n.distance:.1f} m"
    )


def turn_see(parts: dict[str, str], label: str, cands: Sequence[Nearby]) -> MapAnswer:
    """Whether a unit of the label lies within FOV/2 of ahead after the turn."""
    turn = parts.get("turn", "around")
    t = 90.0 if "left" in turn else -90.0 if "right" in turn else 180.0
    seen = [n for n in cands if abs(wrap(n.bearing - t)) <= FOV / 2]
    why = f"after a {t:.0f} deg turn, {len(seen)} {label} within {FOV / 2:.0f} deg of ahead"
    return MapAnswer("yes" if seen else "no", "turn_see", True, why)


def turn_angle(label: str, cands: Sequence[Nearby]) -> MapAnswer:
    """How far to turn to face the nearest unit of the label, to the nearest 90 degrees."""
    if not cands:
        return MapAnswer("", "turn_angle", False, f"no {label} within {AROUND:.0f} m")
    n = cands[0]
    deg = int(round(abs(n.bearing) / 90.0)) * 90
    way = "left" if n.bearing > 0 else "right"
    return MapAnswer(
        f"{deg} degrees", "turn_angle", True, f"unit {n.unit_id} at {n.bearing:.0f} deg ({way})"
    )


_CANON = {"ahead": "front", "back": "behind"}


def _direction_class(option: str) -> str | None:
    for w in ("left", "right", "front", "ahead", "behind", "back"):
        if re.search(rf"\b{w}\b", option):
            return _CANON.get(w, w)
    return None


def which_side(parts: dict[str, str], label: str, cands: Sequence[Nearby]) -> MapAnswer:
    """Which of the offered directions (left/right by default; all four for "where is X?")
    the nearest unit lies in, in the words offered ("front", "behind", "back", "left")."""
    if not cands:
        return MapAnswer("", "which_side", False, f"no {label} within {AROUND:.0f} m")
    n = cands[0]
    offered = [parts.get("a", "left"), parts.get("b", "right")]
    if "where" in parts:
        offered = ["front", "left", "right", "behind"]
    classes = [_direction_class(o) for o in offered]
    centre = {"left": 90.0, "right": -90.0, "front": 0.0, "behind": 180.0}
    scored = [
        (abs(wrap(n.bearing - centre[c])), o, c)
        for o, c in zip(offered, classes, strict=True)
        if c is not None
    ]
    if not scored:
        return MapAnswer("", "which_side", False, "no direction among the options")
    _, option, cls = min(scored)
    word = "back" if re.search(r"\bback\b", option) else cls
    return MapAnswer(word, "which_side", True, f"unit {n.unit_id} at {n.bearing:.0f} deg")


def up_down(parts: dict[str, str], label: str, cands: Sequence[Nearby]) -> MapAnswer:
    """Up or down (above or below) from eye height to the nearest unit's middle."""
    if not cands:
        return MapAnswer("", "up_down", False, f"no {label} within {AROUND:.0f} m")
    n = cands[0]
    mid = (n.z_min + n.z_max) / 2.0
    offered = f"{parts.get('a', '')} {parts.get('b', '')}"
    up = mid >= EYE
    if re.search(r"\b(?:above|below|under|over)\b", offered):
        word = "above" if up else "below"
    elif re.search(r"\b(?:higher|lower)\b", offered):
        word = "higher" if up else "lower"
    else:
        word = "up" if up else "down"
    if "a" in parts and "b" not in parts and parts["a"] in ("up", "down"):  # "should I look up?"
        word = "yes" if (parts["a"] == "up") == up else "no"
    why = f"unit {n.unit_id} middle at {mid:.2f} m, eyes at {EYE:.1f} m"
    return MapAnswer(word, "up_down", True, why)


def on_top(base: Nearby, units: Sequence[Nearby]) -> list[Nearby]:
    """The units resting on `base`: centre over its footprint, bottom ON_RISE above its own."""
    x0, y0, x1, y1 = base.footprint
    return [
        n
        for n in units
        if n.unit_id != base.unit_id
        and n.z_min >= base.z_min + ON_RISE
        and x0 - 0.05 <= (n.footprint[0] + n.footprint[2]) / 2 <= x1 + 0.05
        and y0 - 0.05 <= (n.footprint[1] + n.footprint[3]) / 2 <= y1 + 0.05
    ]


def _base(
    parts: dict[str, str], where: Surroundings, match: Match, key: str = "base"
) -> Nearby | None:
    """The unit a question names as its base ("the table at my two o'clock"); it may be
    the one I stand at."""
    phrase = parts.get(key, "")
    label = match(phrase, list(where.labels.values()))
    sector = sector_of(parts) if key == "base" else None
    units = [n for n in where.nearby if n.label == label and in_sector(n, sector)]
    return pick(units, label, phrase) if units else None


def on_exists(parts: dict[str, str], where: Surroundings, match: Match) -> MapAnswer:
    """Whether anything rests on the base."""
    base = _base(parts, where, match)
    if base is None:
        return MapAnswer("", "on_exists", False, f"no {parts.get('base')!r} nearby")
    on = on_top(base, where.nearby)
    why = f"{len(on)} unit(s) on unit {base.unit_id} ({base.label})"
    return MapAnswer("yes" if on else "no", "on_exists", True, why)


def nearest(near: Sequence[Nearby]) -> MapAnswer:
    """The nearest unit (not the one I stand at, none a wall hides)."""
    if not near:
        return MapAnswer("nothing", "nearest", True, f"no unit within {AROUND:.0f} m")
    n = near[0]
    return MapAnswer(n.label, "nearest", True, f"unit {n.unit_id} at {n.distance:.1f} m")


def next_to(
    kind: str, parts: dict[str, str], where: Surroundings, near: Sequence[Nearby], match: Match
) -> MapAnswer:
    """next_to: the unit whose centre is nearest the named unit's (within BESIDE m), not on
    it; under: the nearest unit whose centre lies over its footprint, below its top."""
    base = _base(parts, where, match, key="object")
    if base is None:
        return MapAnswer("", kind, False, f"no {parts.get('object')!r} nearby")
    x0, y0, x1, y1 = base.footprint
    bx, by = (x0 + x1) / 2, (y0 + y1) / 2
    on = {n.unit_id for n in on_top(base, where.nearby)}
    found = []
    for n in near:
        if n.unit_id == base.unit_id or n.unit_id in on:
            continue
        cx, cy = (n.footprint[0] + n.footprint[2]) / 2, (n.footprint[1] + n.footprint[3]) / 2
        gap = math.hypot(cx - bx, cy - by)
        if kind == "under":
            over = x0 <= cx <= x1 and y0 <= cy <= y1
            if over and n.z_max <= base.z_max + 0.15 and n.z_min < base.z_max - 0.2:
                found.append((gap, n))
        elif gap <= BESIDE:
            found.append((gap, n))
    if not found:
        return MapAnswer("nothing", kind, True, f"nothing {kind} unit {base.unit_id}")
    gap, n = min(found, key=lambda t: t[0])
    return MapAnswer(n.label, kind, True, f"unit {n.unit_id} {gap:.1f} m from {base.unit_id}")


def between(
    parts: dict[str, str], near: Sequence[Nearby], match: Match, labels: Sequence[str]
) -> MapAnswer:
    """The unit nearest the line between the two named units' centres (within 0.6 m of it,
    in its middle 70%)."""
    ends = []
    for key in ("a", "b"):
        label = match(parts[key], labels)
        unit = pick(near, label, parts[key]) if label else None
        if unit is None:
            return MapAnswer("", "between", False, f"no {parts[key]!r} nearby")
        ends.append(unit)
    (ax, ay), (bx, by) = (_centre(n) for n in ends)
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy or 1e-9
    found = []
    for n in near:
        if n.unit_id in (ends[0].unit_id, ends[1].unit_id):
            continue
        cx, cy = _centre(n)
        t = ((cx - ax) * dx + (cy - ay) * dy) / length2
        off = abs((cx - ax) * dy - (cy - ay) * dx) / math.sqrt(length2)
        if 0.15 <= t <= 0.85 and off <= 0.6:
            found.append((off, n))
    if not found:
        return MapAnswer("nothing", "between", True, "nothing near the line between them")
    off, n = min(found, key=lambda x: x[0])
    return MapAnswer(n.label, "between", True, f"unit {n.unit_id} {off:.2f} m off the line")


def which_of(
    parts: dict[str, str], near: Sequence[Nearby], match: Match, labels: Sequence[str]
) -> MapAnswer:
    """Which of the two named objects lies in the place asked, in the question's words."""
    sector = sector_of(parts)
    if sector is None:
        return MapAnswer("", "which_of", False, "no side, hour or direction to choose by")
    scored = []
    for key in ("a", "b"):
        label = match(parts[key], labels)
        unit = pick(near, label, parts[key]) if label else None
        if unit is None:
            return MapAnswer("", "which_of", False, f"no {parts[key]!r} nearby")
        scored.append((abs(wrap(unit.bearing - sector[0])), parts[key], unit))
    off, words, unit = min(scored, key=lambda x: x[0])
    return MapAnswer(words, "which_of", True, f"unit {unit.unit_id} {off:.0f} deg off the place")


def _centre(n: Nearby) -> tuple[float, float]:
    return (n.footprint[0] + n.footprint[2]) / 2, (n.footprint[1] + n.footprint[3]) / 2


def count_on(
    parts: dict[str, str], where: Surroundings, near: Sequence[Nearby], match: Match
) -> MapAnswer:
    """How many units of the label rest on the base named (its place picks which base)."""
    labels = list(where.labels.values())
    obj, base_phrase = parts.get("object", ""), parts.get("base", "")
    sector = sector_of(parts)
    base_label = match(base_phrase, labels)
    bases = [
        n
        for n in where.nearby  # the base may be what I stand at
        if n.label == base_label and (sector is None or in_sector(n, sector))
    ]
    if not bases:
        return MapAnswer("", "count_on", False, f"no {base_phrase!r} nearby")
    base = pick(bases, base_label, base_phrase)
    assert base is not None
    label = match(obj, labels)
    if label is None:
        return MapAnswer("", "count_on", False, f"no unit is a {obj!r}")
    on = [n for n in on_top(base, where.nearby) if n.label == label]
    return MapAnswer(
        str(len(on)), "count_on", True, f"{len(on)} x {label} on unit {base.unit_id} ({base.label})"
    )


def divisible(
    parts: dict[str, str], near: Sequence[Nearby], label: str | None, obj: str
) -> MapAnswer:
    """Whether the count of the label (in the place asked, else around) divides by k."""
    k = _number(parts.get("k", ""))
    if not k:
        return MapAnswer("", "divisible", False, f"{parts.get('k')!r} is no divisor")
    if label is None:
        return MapAnswer("", "divisible", False, f"no unit is a {obj!r}")
    sector = sector_of(parts)
    count = sum(n.label == label and n.distance <= AROUND and in_sector(n, sector) for n in near)
    return MapAnswer(
        "yes" if count % k == 0 else "no",
        "divisible",
        True,
        f"{count} x {label}; {count} mod {k} = {count % k}",
    )


def direction_word(bearing: float) -> str:
    """forward / left / right / backward for a bearing in degrees (+ = left)."""
    if abs(bearing) <= 45.0:
        return "forward"
    if 45.0 < bearing <= 135.0:
        return "left"
    if -135.0 <= bearing < -45.0:
        return "right"
    return "backward"


def direction(kind: str, label: str, cands: list[Nearby]) -> MapAnswer:
    """Which way the nearest unit of the label lies."""
    if not cands:
        return MapAnswer("", kind, False, f"no {label} within {AROUND:.0f} m in this room")
    n = cands[0]
    return MapAnswer(
        direction_word(n.bearing), kind, True, f"unit {n.unit_id} at {n.bearing:.0f} deg"
    )
