"""Numba kernel of `nav.planner.geodesic`: the second-order fast marching method from one
source cell, the travel time scikit-fmm's `travel_time` gives, bit for bit.

The zero level set lies half a cell around the source (phi -1 there, +1 elsewhere), so the
source and its open neighbours start settled. A cell's arrival solves, over the axes with
a settled neighbour, sum_axis k (t - tp)^2 = 1 / speed^2 (k = 1 / dx^2), where tp is the
nearer settled neighbour's time, or (4 t1 - t2) / 3 with weight 9/4 when the cell beyond it
is settled and no later (the source's time counts negative there: it lies across the zero
level set). A negative discriminant drops one axis at a time and takes the smaller. The
march settles the cheapest cell of a binary heap, and every cell of the same time with it,
then updates their neighbours and, across a settled neighbour, the cell beyond.

What makes the bits equal to scikit-fmm's: the same floating-point expressions in the same
order, the same heap (sift rules, ties to the right child, re-sift on update) and the same
order of pushes and updates; `tests/test_nav_planner.py` holds the two equal on random
grids. Over scikit-fmm's C++ marcher it saves that marcher's fixed work over the whole
window (a band settles only the cells it needs), index arithmetic (a padded grid of rows
and columns) and a separate settled flag in the stencil (unsettled cells read +inf).
"""

from __future__ import annotations

import math

import numba
import numpy as np

FAR, NARROW, SETTLED, BLOCKED = 0, 1, 2, 3
BIG = np.finfo(np.float64).max  # "no neighbour" in the stencil, as scikit-fmm's maxDouble
ONE_THIRD = 1.0 / 3.0
NINE_QUARTERS = 9.0 / 4.0
PAD = 2  # blocked border: the stencil reaches two cells, so no bounds checks


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _solve(r, c, skip_axes, t, inv_speed2, sr, sc, k):  # pragma: no cover - numba
    """(solved, time) of cell (r, c) from its settled neighbours along the axes not in the
    bit mask `skip_axes`; t is +inf on unsettled cells."""
    a = 0.0
    b = 0.0
    q = 0.0
    for axis in range(2):
        if skip_axes & (1 << axis):
            continue
        dr = 1 if axis == 0 else 0
        dc = 1 - dr
        near = BIG
        far = BIG
        for step in (-1, 1):
            r1 = r + step * dr
            c1 = c + step * dc
            t1 = t[r1, c1]
            if t1 < near:
                near = t1
                r2 = r1 + step * dr
                c2 = c1 + step * dc
                t2 = t[r2, c2]
                if t2 <= near:  # the second-order stencil (the far value is not reset
                    far = t2  # when the other side's nearer neighbour has none)
                    if (r1 == sr and c1 == sc) or (r2 == sr and c2 == sc):
                        far = -far
        if far < BIG:
            tp = ONE_THIRD * (4 * near - far)
            a += k * NINE_QUARTERS
            b -= k * 2 * NINE_QUARTERS * tp
            q += k * NINE_QUARTERS * (tp * tp)
        elif near < BIG:
            a += k
            b -= k * 2 * near
            q += k * (near * near)
    q -= inv_speed2[r, c]
    det = b * b - 4 * a * q
    if det >= 0:
        return True, (-b + math.sqrt(det)) * 0.5 / a
    return False, 0.0


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _arrival(r, c, t, inv_speed2, sr, sc, k):  # pragma: no cover - numba
    """The cell's time from its settled neighbours; with a negative discriminant, the
    smaller of the one-axis solutions (each of which, failing, solves with no axis). One
    `_solve` in the loop, not four: this is inlined where it is called."""
    solved, v = _solve(r, c, 0, t, inv_speed2, sr, sc, k)
    if solved:
        return v
    best = 0.0
    for skip in (1, 2):
        v = np.inf
        for axes in (skip, 3):
            solved, x = _solve(r, c, axes, t, inv_speed2, sr, sc, k)
            if solved:
                v = x
                break
        if skip == 1 or v < best:
            best = v
    return best


# `_arrival` called, not inlined, where cells are rare (the first narrow band, the cell beyond
# a settled neighbour): fewer inlined copies compile faster.
_arrival_called = numba.njit(cache=True, nogil=True, error_model="numpy")(_arrival.py_func)


@numba.njit(cache=True, nogil=True, inline="always")
def _rise(keys, entries, slot_of, low, pos):  # pragma: no cover - numba
    """Move the heap item at `pos` toward the root (not past `low`) while it is smaller."""
    key = keys[pos]
    entry = entries[pos]
    while pos > low:
        parent = (pos - 1) >> 1
        if key < keys[parent]:
            keys[pos] = keys[parent]
            entries[pos] = entries[parent]
            slot_of[entries[pos]] = pos
            pos = parent
        else:
            break
    keys[pos] = key
    entries[pos] = entry
    slot_of[entry] = pos


@numba.njit(cache=True, nogil=True, inline="always")
def _sink(keys, entries, slot_of, size, pos):  # pragma: no cover - numba
    """Move the heap item at `pos` down to a leaf along the smaller children (the right one
    on ties), then back up while it is smaller than its parent."""
    top = pos
    key = keys[pos]
    entry = entries[pos]
    child = 2 * pos + 1
    while child < size:
        right = child + 1
        if right < size and not (keys[child] < keys[right]):
            child = right
        keys[pos] = keys[child]
        entries[pos] = entries[child]
        slot_of[entries[pos]] = pos
        pos = child
        child = 2 * pos + 1
    keys[pos] = key
    entries[pos] = entry
    slot_of[entry] = pos
    _rise(keys, entries, slot_of, top, pos)


@numba.njit(cache=True, nogil=True, inline="always")
def _update(keys, entries, slot_of, size, entry, value):  # pragma: no cover - numba
    """Give heap entry `entry` the key `value` and restore the heap."""
    pos = slot_of[entry]
    old = keys[pos]
    keys[pos] = value
    if value > old:
        _sink(keys, entries, slot_of, size, pos)
    if keys[pos] != value:
        return
    _rise(keys, entries, slot_of, 0, pos)


@numba.njit(cache=True, nogil=True, inline="always")
def _push(keys, entries, slot_of, size, cells, n_entries, r, c, value):  # pragma: no cover
    """Push cell (r, c) with key `value` as heap entry `n_entries`; cells: (row_of, col_of,
    entry_of). Returns the heap's new size and the next entry."""
    row_of, col_of, entry_of = cells
    keys[size] = value
    row_of[n_entries] = r
    col_of[n_entries] = c
    entries[size] = n_entries
    slot_of[n_entries] = size
    entry_of[r, c] = n_entries
    _rise(keys, entries, slot_of, 0, size)
    return size + 1, n_entries + 1


@numba.njit(cache=True, nogil=True, error_model="numpy")
def travel_time_from(  # pragma: no cover - numba
    blocked: np.ndarray,
    speed: np.ndarray,
    source_row: int,
    source_col: int,
    dx: float,
    band: float,
) -> np.ndarray:
    """[H, W] time from the zero level set half a cell around the source cell; inf where the
    march did not settle a cell (blocked, cut off, or past `band` when `band` > 0).

    Args:
        blocked: [H, W] bool, False at the source.
        speed: [H, W] float64 > 0 on open cells.
        source_row, source_col: the source cell, with at least one open 4-neighbour.
        dx: cell size.
        band: stop once the cheapest unsettled time exceeds it; 0: march everything.
    """
    h, w = blocked.shape
    flag = np.full((h + 2 * PAD, w + 2 * PAD), BLOCKED, np.int8)
    inv_speed2 = np.zeros((h + 2 * PAD, w + 2 * PAD))
    n_open = 0
    for r in range(h):
        for c in range(w):
            if not blocked[r, c]:
                flag[r + PAD, c + PAD] = FAR
                inv_speed2[r + PAD, c + PAD] = 1 / (speed[r, c] * speed[r, c])
                n_open += 1
    t = np.full((h + 2 * PAD, w + 2 * PAD), np.inf)
    sr, sc = source_row + PAD, source_col + PAD
    k = 1 / dx / dx
    # Settled at the start: the source (a crossing along each axis with an open neighbour,
    # at dx * phi / (phi - phi_n) = dx / 2) and each open neighbour (one crossing).
    to_level_set = dx * -1.0 / (-1.0 - 1.0)
    inverse_sum = 0.0
    for dr, dc in ((1, 0), (0, 1)):
        if flag[sr - dr, sc - dc] != BLOCKED or flag[sr + dr, sc + dc] != BLOCKED:
            inverse_sum += 1 / to_level_set / to_level_set
    t[sr, sc] = abs(-math.sqrt(1 / inverse_sum) / speed[source_row, source_col])
    flag[sr, sc] = SETTLED
    n_settled = 1
    to_level_set = dx * 1.0 / (1.0 - -1.0)
    for dr, dc in ((-1, 0), (0, -1), (0, 1), (1, 0)):
        r, c = sr + dr, sc + dc
        if flag[r, c] == FAR:
            inverse = 0.0 + 1 / to_level_set / to_level_set
            t[r, c] = abs(math.sqrt(1 / inverse) / speed[r - PAD, c - PAD])
            flag[r, c] = SETTLED
            n_settled += 1
    capacity = max(n_open - n_settled, 1)
    keys = np.empty(capacity)
    entries = np.empty(capacity, np.int64)
    slot_of = np.empty(capacity, np.int64)
    row_of = np.empty(capacity, np.int64)
    col_of = np.empty(capacity, np.int64)
    entry_of = np.empty(flag.shape, np.int64)
    cells = (row_of, col_of, entry_of)
    n_entries = 0
    size = 0
    # The first narrow band: cells next to a settled one, in address order (all lie within
    # two cells of the source).
    for r in range(sr - 2, sr + 3):
        for c in range(sc - 2, sc + 3):
            if flag[r, c] != FAR:
                continue
            if (
                flag[r - 1, c] == SETTLED
                or flag[r + 1, c] == SETTLED
                or flag[r, c - 1] == SETTLED
                or flag[r, c + 1] == SETTLED
            ):
                flag[r, c] = NARROW
                v = _arrival_called(r, c, t, inv_speed2, sr, sc, k)
                size, n_entries = _push(keys, entries, slot_of, size, cells, n_entries, r, c, v)
    batch = np.empty(capacity, np.int64)
    while size > 0:
        value = keys[0]
        if band != 0 and value > band:
            break
        n_batch = 0
        while True:  # settle the cheapest cell and every cell of the same time
            entry = entries[0]
            batch[n_batch] = entry
            n_batch += 1
            flag[row_of[entry], col_of[entry]] = SETTLED
            t[row_of[entry], col_of[entry]] = keys[0]
            size -= 1
            keys[0] = keys[size]
            entries[0] = entries[size]
            slot_of[entries[0]] = 0
            _sink(keys, entries, slot_of, size, 0)
            if not (size > 0 and keys[0] == value):
                break
        for i in range(n_batch):
            r = row_of[batch[i]]
            c = col_of[batch[i]]
            for axis in range(2):
                dr = 1 if axis == 0 else 0
                dc = 1 - dr
                for step in (-1, 1):
                    r1 = r + step * dr
                    c1 = c + step * dc
                    state = flag[r1, c1]
                    if state < SETTLED:  # far or narrow
                        v = _arrival(r1, c1, t, inv_speed2, sr, sc, k)
                        if v == 0:
                            continue
                        if state == NARROW:
                            _update(keys, entries, slot_of, size, entry_of[r1, c1], v)
                        else:
                            flag[r1, c1] = NARROW
                            size, n_entries = _push(
                                keys, entries, slot_of, size, cells, n_entries, r1, c1, v
                            )
                    elif state == SETTLED:  # the cell beyond, whose second-order stencil
                        r2 = r1 + step * dr  # this cell completes
                        c2 = c1 + step * dc
                        if flag[r2, c2] == NARROW:
                            v = _arrival_called(r2, c2, t, inv_speed2, sr, sc, k)
                            if v != 0:
                                _update(keys, entries, slot_of, size, entry_of[r2, c2], v)
    return t[PAD : PAD + h, PAD : PAD + w].copy()
