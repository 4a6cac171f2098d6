"""Floor the agent reaches only through a passage too narrow to pass (`narrow_passages`):
`layout_from_scan` warns of it (`glmap_tools.worlds.scan`), and `glmap sim episodes` draws
no start that needs it."""

from __future__ import annotations

import numpy as np

from glmap_tools.sim.layout import Layout
from glmap_tools.sim.navgrid import AGENT_RADIUS, MIN_PASSAGE_CELLS, build_nav_grid

MIN_PART_AREA = 0.25  # m^2: smaller pockets behind a narrow passage are not worth a warning


def narrow_passages(layout: Layout) -> list[str]:
    """One sentence per stretch of floor that the agent reaches only through a passage
    narrower than `MIN_PASSAGE_CELLS` cells of centre positions (about 0.56 m between
    obstacles: its 0.36 m body, a cell's rounding each side and 3 cells to line up in).

    Why such a passage is impassable rather than a steering problem: the agent turns in
    30 deg steps from its start heading and moves 0.25 m at a time, so its heading can be up
    to 15 deg off a passage's axis; through a one-cell (0.41 m) gap it must keep its centre
    on a 5 cm line, which a 0.25 m step leaves unless the heading is within about 6 deg of
    the axis (about 1 start heading in 3). `glmap sim episodes` draws no start that needs
    such a passage.
    """
    grid = build_nav_grid(layout)
    labels = grid.passable_parts(MIN_PASSAGE_CELLS)
    counts = np.bincount(labels.ravel())
    counts[0] = 0
    if counts.sum() == 0:
        return []
    main = int(np.argmax(counts))
    gap = 2 * AGENT_RADIUS + (MIN_PASSAGE_CELLS + 1) * grid.cell
    out = []
    cell_area = grid.cell * grid.cell
    for label in np.nonzero(counts)[0]:
        if label == main or counts[label] * cell_area < MIN_PART_AREA:
            continue
        cells = np.argwhere(labels == label)
        xy = grid.to_world(cells).mean(axis=0)
        room_id = layout.room_at(xy)
        room = f" in room {room_id} ({layout.room(room_id).name!r})" if room_id else ""
        out.append(
            f"the floor around ({xy[0]:.2f}, {xy[1]:.2f}){room}, "
            f"{counts[label] * cell_area:.1f} m^2, is joined to the rest only through a "
            f"passage narrower than about {gap:.2f} m between obstacles: the agent "
            f"({2 * AGENT_RADIUS:.2f} m across, 30 deg turns) cannot be expected to pass it, "
            "and glmap sim episodes draws no start that needs it. Move the furniture that "
            "narrows it if the real room is wider there."
        )
    return out
