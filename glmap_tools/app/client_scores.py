"""The client's f_S of the episode's goal (value_map's scores and priors): checked, held by
the session's NavSession, and shown as value_map shows them."""

from __future__ import annotations

from typing import TYPE_CHECKING

from glmap_tools.app import nav_steps
from glmap_tools.app.session import Session, locked
from glmap_tools.app.sim_results import HeldScores
from glmap_tools.errors import InvalidInputError

if TYPE_CHECKING:
    from glmap_tools.map import GLMap
    from glmap_tools.nav.scorers import ClientScores

# Imports inside functions stay there: gaussians, language.embed, scipy, numba load on first use:
# the tools load before these do, in the server and the in-process toolset alike.


def check_client_scores(
    glmap: GLMap, scores: dict[int, float], priors: dict[str, float]
) -> tuple[dict[int, float], dict[str, float], dict[int, int]]:
    """(scores by live id, priors, {fused id: live id}) or raise before anything changes."""
    from glmap_tools.nav.scorers import MAX_KIND_CHARS, check_unit_score, kind_pattern

    live: dict[int, float] = {}
    followed: dict[int, int] = {}
    for uid, score in scores.items():
        value = check_unit_score(score, f"unit {uid}")
        unit = int(uid)
        while unit in glmap.fused_into and not (unit in glmap.instances or unit in glmap.regions):
            unit = glmap.fused_into[unit]
        if unit != uid:
            followed[int(uid)] = unit
        glmap.unit(unit)  # an unknown id raises UnknownIdError with the closest one
        live[unit] = max(value, live.get(unit, 0.0)) if unit in live else value
    kinds: dict[str, float] = {}
    for kind, score in priors.items():
        kind_pattern(kind)  # an empty kind raises
        if len(kind) > MAX_KIND_CHARS:  # checked here, not where held kinds are matched
            raise InvalidInputError(
                f"prior kind {kind[:40]!r}... has {len(kind)} characters, more than "
                f"{MAX_KIND_CHARS}; name a kind of room or region in a few words, e.g. 'kitchen'."
            )
        kinds[" ".join(kind.lower().split())] = check_unit_score(score, f"kind {kind!r}")
    return live, kinds, followed


def set_client_scores(
    session: Session,
    scores: dict[int, float] | None,
    priors: dict[str, float] | None,
    clear: bool,
) -> HeldScores:
    """Check and keep the client's f_S of the episode's goal; return what is held now
    (scores by unit, priors by region kind, and the fused ids whose scores moved to the
    unit they became). Nothing changes on an error."""
    from glmap_tools.nav.scorers import MAX_PRIORS, ClientScores

    _, nav = nav_steps.running(session)
    with locked(session) as glmap:
        units, kinds, followed = check_client_scores(glmap, scores or {}, priors or {})
        kept = {} if clear or nav.client is None else nav.client.priors
        held = len(kept.keys() | kinds.keys())
        if held > MAX_PRIORS:
            raise InvalidInputError(
                f"priors would hold {held} region kinds, more than {MAX_PRIORS}; give the "
                "kinds that matter for this goal (clear: true drops those held)."
            )
        if clear or nav.client is None:
            nav.client = ClientScores(nav.goal)
        nav.client.units.update(units)
        nav.client.priors.update(kinds)
        followed.update(nav.client.follow(glmap.fused_into))
        return held_scores(glmap, nav.client, followed)


def held_scores(
    glmap: GLMap, client: ClientScores, followed: dict[int, int] | None = None
) -> HeldScores:
    """The client's scores as value_map shows them (see `set_client_scores`)."""
    from glmap_tools.nav.scorers import kind_pattern

    regions = sorted((r.id, r.text.lower()) for r in glmap.regions.values())
    out = HeldScores(
        scores=[(u, glmap.unit(u).kind, s) for u, s in sorted(client.units.items())],
        priors=[
            (k, s, [r for r, t in regions if kind_pattern(k).search(t)])
            for k, s in sorted(client.priors.items())
        ],
    )
    if followed:
        out.followed = [f"{a}->{b}" for a, b in sorted(followed.items())]
    return out
