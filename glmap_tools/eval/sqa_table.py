"""The tables of `glmap eval sqa`: EM-1 and EM-R1 per agent with intervals, paired
differences, per-type EM-1 and the glmap agent's localisation (`summarize`); the same per
phrasing family (`summarize_forms`); and whether the offline reader reads a situation as the
generator wrote it (`reading_ok`)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from glmap_tools.eval.stats import bootstrap_mean, paired_difference

# Imports inside functions stay there: gaussians, gymnasium load on first use: `glmap` imports
# every command module to build its parser.

LOCALISED_M, LOCALISED_DEG = 1.0, 45.0  # a pose counts as localised within these


def reading_ok(text: str, truth: dict[str, Any]) -> bool:
    """Does the offline reader read the situation as the generator wrote it (anchor,
    facing, constraint objects and sides/hours)?"""
    from glmap_tools.sqa.reading import read_situation

    r = read_situation(text)
    cons = [[c.object, c.side or c.clock] for c in r.constraints]
    return (
        r.anchor == truth["anchor"]
        and r.facing == truth["facing"]
        and cons == [list(c) for c in truth["constraints"]]
    )


def summarize_forms(records: list[dict[str, Any]]) -> str:
    """Markdown per phrasing family: situations (reading accuracy, localisation, EM-1 of
    glmap on their questions) and questions (family recognised, EM-1 glmap / text-only,
    share supported), with the held-out forms marked and pooled."""
    rows = [r for r in records if "situation_form" in r]
    if not rows:
        return ""
    from glmap_tools.sqa.more_phrasings import HELD_OUT as HELD_OUT_2
    from glmap_tools.worlds.qa_phrasings import HELD_OUT

    held_s = {v for v in HELD_OUT.values() if isinstance(v, str)}
    held_s |= {f"r2:{v}" for v in HELD_OUT_2.values() if isinstance(v, str)}
    held_q = {f"{k}/{v}" for k, v in HELD_OUT.items() if isinstance(v, int)}
    held_q |= {f"r2:{k}/{v}" for k, v in HELD_OUT_2.items() if isinstance(v, int)}
    lines = _situation_form_table(rows, held_s)
    lines += _question_form_table(rows, held_q)
    lines.append("")
    lines += _held_out_lines(rows, held_s, held_q)
    both = [r for r in rows if r["situation_form"] in held_s and r["question_form"] in held_q]
    if both:
        n_both = sum(r["agent"] == "glmap" for r in both)
        lines.append(
            f"- held-out situation and question form together: {n_both} questions, "
            f"EM-1 glmap {_em(both, 'glmap')} / text-only {_em(both, 'text-only')}"
        )
    return "\n".join(lines) + "\n"


def _em(rs: list[dict[str, Any]], agent: str) -> str:
    """Mean EM-1 of `agent` on the records `rs`, to 2 decimals ('-' when none)."""
    v = [r["em1"] for r in rs if r["agent"] == agent]
    return f"{np.mean(v):.2f}" if v else "-"


def _located(rs: list[dict[str, Any]]) -> tuple[str, str, int]:
    """(share read right, share localised, situations) of glmap over the situations of `rs`."""
    sit = {}
    for r in rs:
        if r["agent"] == "glmap":
            sit[(r["scene"], r["situation"], tuple(r.get("stand", ())))] = r
    ok = [
        "err_m" in r and r["err_m"] <= LOCALISED_M and r["err_deg"] <= LOCALISED_DEG
        for r in sit.values()
    ]
    read = [bool(r.get("reading_ok")) for r in sit.values()]
    return f"{np.mean(read):.2f}", f"{np.mean(ok):.2f}", len(sit)


def _situation_form_table(rows: list[dict[str, Any]], held_s: set[str]) -> list[str]:
    """Markdown lines: per situation form, reading, localisation and EM-1 of glmap."""
    lines = ["", "| situation form | held out | situations | reading | localised | EM-1 glmap |"]
    lines.append("|---|---|---|---|---|---|")
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault(r["situation_form"], []).append(r)
    for name, rs in sorted(groups.items()):
        rd, loc, n = _located(rs)
        mark = "yes" if name in held_s else ""
        lines.append(f"| {name} | {mark} | {n} | {rd} | {loc} | {_em(rs, 'glmap')} |")
    return lines


def _question_form_table(rows: list[dict[str, Any]], held_q: set[str]) -> list[str]:
    """Markdown lines: per question form, family read, EM-1 glmap / text-only, supported."""
    lines = [
        "",
        "| question form | held out | questions | family read | EM-1 glmap | EM-1 text-only "
        "| supported (glmap) |",
        "|---|---|---|---|---|---|---|",
    ]
    qgroups: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        qgroups.setdefault(r["question_form"], []).append(r)
    for name, rs in sorted(qgroups.items()):
        g = [r for r in rs if r["agent"] == "glmap"] or rs
        read = np.mean([r["read"] == r["type"] for r in g])
        sup = np.mean([r["supported"] for r in g])
        mark = "yes" if name in held_q else ""
        lines.append(
            f"| {name} | {mark} | {len(g)} | {read:.2f} | {_em(rs, 'glmap')} "
            f"| {_em(rs, 'text-only')} | {sup:.2f} |"
        )
    return lines


def _held_out_lines(rows: list[dict[str, Any]], held_s: set[str], held_q: set[str]) -> list[str]:
    """Markdown bullets: held-out and tuned forms pooled (per set when there are two)."""
    lines: list[str] = []
    sets = [("", rows)]
    if any(r.get("round", 1) == 2 for r in rows):
        sets = [
            (f"{name}, ", [r for r in rows if r.get("round", 1) == n])
            for n, name in ((1, "first set"), (2, "second set"))
        ]
    for (prefix, part), (held, pick) in itertools.product(
        sets, (("held-out", True), ("tuned", False))
    ):
        label = prefix + held
        sit = [r for r in part if (r["situation_form"] in held_s) == pick]
        qs = [r for r in part if (r["question_form"] in held_q) == pick]
        if sit:
            rd, loc, n = _located(sit)
            lines.append(
                f"- {label} situation forms: {n} situations, reading {rd}, localised {loc}, "
                f"EM-1 glmap {_em(sit, 'glmap')} / text-only {_em(sit, 'text-only')} on their "
                "questions"
            )
        g = [r for r in qs if r["agent"] == "glmap"]
        if g:
            sup = [r for r in g if r["supported"]]
            fam = np.mean([r["read"] == r["type"] for r in g])
            lines.append(
                f"- {label} question forms: {len(g)} questions, family read {fam:.2f}, EM-1 "
                f"glmap {_em(qs, 'glmap')} (supported {len(sup)}: "
                f"{np.mean([r['em1'] for r in sup]) if sup else float('nan'):.2f}; unsupported "
                f"{len(g) - len(sup)}), text-only {_em(qs, 'text-only')}"
            )
    return lines


def summarize(records: list[dict[str, Any]], agents: Sequence[str], resamples: int = 2000) -> str:
    """Markdown: EM-1, EM-R1 per agent with intervals, paired differences, per-type EM-1,
    and the localisation of the glmap agent."""

    def values(agent: str, key: str) -> np.ndarray:
        rows = sorted(
            (r for r in records if r["agent"] == agent),
            key=lambda r: (r["scene"], r["question_id"]),
        )
        return np.array([float(r[key]) for r in rows])

    def cell(i: Any) -> str:
        return f"{i.mean:.3f} [{i.low:.3f}, {i.high:.3f}]"

    lines = [
        "| agent | EM-1 | EM-R1 | questions |",
        "|---|---|---|---|",
    ]
    for agent in agents:
        e1, er = values(agent, "em1"), values(agent, "em_r1")
        if len(e1) == 0:
            continue
        lines.append(
            f"| {agent} | {cell(bootstrap_mean(e1, resamples=resamples))} | "
            f"{cell(bootstrap_mean(er, resamples=resamples))} | {len(e1)} |"
        )
    if "glmap" in agents:
        lines += ["", "| glmap minus | EM-1 difference [95%] |", "|---|---|"]
        base = values("glmap", "em1")
        for agent in agents:
            if agent == "glmap" or len(values(agent, "em1")) != len(base):
                continue
            d = paired_difference(base, values(agent, "em1"), resamples=resamples)
            lines.append(f"| {agent} | {cell(d)} |")
    types = sorted({r["type"] for r in records})
    lines += ["", "| type | n | " + " | ".join(agents) + " |", "|---|---|" + "---|" * len(agents)]
    for t in types:
        row = [t, str(sum(1 for r in records if r["type"] == t and r["agent"] == agents[0]))]
        for agent in agents:
            rs = [r for r in records if r["type"] == t and r["agent"] == agent]
            row.append(f"{np.mean([r['em1'] for r in rs]):.2f}" if rs else "-")
        lines.append("| " + " | ".join(row) + " |")
    # One row per situation (its text and true pose; two stand points may share a text):
    # localisation does not depend on the question.
    loc = {}
    for r in records:
        if r["agent"] == "glmap":
            loc[(r["scene"], r["situation"], tuple(r.get("stand", ())))] = r
    if loc:
        ok = np.array(
            [
                float("err_m" in r and r["err_m"] <= LOCALISED_M and r["err_deg"] <= LOCALISED_DEG)
                for r in loc.values()
            ]
        )
        errs = [r["err_m"] for r in loc.values() if "err_m" in r]
        degs = [r["err_deg"] for r in loc.values() if "err_deg" in r]
        lines += [
            "",
            f"Localisation (glmap): within {LOCALISED_M:.0f} m and {LOCALISED_DEG:.0f} deg on "
            f"{cell(bootstrap_mean(ok, resamples=resamples))} of {len(ok)} situations; "
            "median error "
            f"{np.median(errs) if errs else float('nan'):.2f} m, "
            f"{np.median(degs) if degs else float('nan'):.0f} deg; "
            f"{sum('error' in r for r in loc.values())} not located.",
        ]
    return "\n".join(lines) + "\n"
