"""Numba kernels that voxelise a cloud: input scan, block hashing, voxel numbering.

Voxel cell coordinates are floor(p / voxel) - lo + CELL_MARGIN (non-negative, with a block
of empty cells below the smallest one). Voxels are numbered in the order their first point
appears in the input.
"""

from __future__ import annotations

import numba
import numpy as np

from glmap_tools.gaussians._estimator_grid import SLOTS, block_key, hash_slot, slot_of
from glmap_tools.gaussians._int64 import ZERO

CELL_MARGIN = 4  # one block of empty cells below the smallest coordinate
EXPONENT_BITS = 0x7FF0000000000000  # of a float64: all set for inf and NaN
ONE_BITS = 0x3F800000  # float32 1.0; non-negative float32s order as their bits
NEGATIVE_ZERO_BITS = 0x80000000
BLOCK_ROOM_DIVISOR = 32  # points per block the store is first sized for


@numba.njit(cache=True, fastmath={"nnan", "nsz"})
def scan_cloud(points: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """[8] = (points all finite, colours all in [0, 1], point min xyz, point max xyz).

    Args:
        points: [N, 3] float64, C-contiguous, N >= 1.
        colors: [N, 3] float32, C-contiguous.

    Three loops over flat arrays, each vectorised: min/max (no-NaN math lets them vectorise;
    with a NaN the min/max are unspecified but the cloud is refused anyway), the finite test
    on the exponent bits, the colour range on the bits (0 <= bits <= those of 1.0, or -0.0).
    """
    flat = points.reshape(-1)
    lx, ly, lz = flat[0], flat[1], flat[2]
    hx, hy, hz = lx, ly, lz
    for i in range(points.shape[0]):
        x, y, z = flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]
        lx, ly, lz = min(lx, x), min(ly, y), min(lz, z)
        hx, hy, hz = max(hx, x), max(hy, y), max(hz, z)
    bits = flat.view(np.int64)
    not_finite = False
    for i in range(bits.shape[0]):
        not_finite |= (bits[i] & EXPONENT_BITS) == EXPONENT_BITS
    color_bits = colors.reshape(-1).view(np.uint32)
    out_of_range = False
    for i in range(color_bits.shape[0]):
        c = color_bits[i]
        out_of_range |= (c > ONE_BITS) & (c != NEGATIVE_ZERO_BITS)
    out = np.empty(8)
    out[0] = 0.0 if not_finite else 1.0
    out[1] = 0.0 if out_of_range else 1.0
    out[2], out[3], out[4], out[5], out[6], out[7] = lx, ly, lz, hx, hy, hz
    return out


@numba.njit(cache=True)
def _scan_half(k: np.int64, points: np.ndarray, colors: np.ndarray, out: np.ndarray) -> None:
    half = points.shape[0] // 2
    start, stop = (ZERO, np.int64(half)) if k == 0 else (np.int64(half), np.int64(points.shape[0]))
    out[k] = scan_cloud(points[start:stop], colors[start:stop])


@numba.njit(cache=True, parallel=True)
def _scan_halves_parallel(points: np.ndarray, colors: np.ndarray, out: np.ndarray) -> None:
    for k in numba.prange(2):  # nothing else here: array code would spawn parfors
        _scan_half(np.int64(k), points, colors, out)


@numba.njit(cache=True)
def scan_cloud_halves(points: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """`scan_cloud` of N >= 2 points, its two halves on two threads."""
    halves = np.empty((2, 8))
    _scan_halves_parallel(points, colors, halves)
    out = np.empty(8)
    out[0], out[1] = min(halves[0, 0], halves[1, 0]), min(halves[0, 1], halves[1, 1])
    for a in range(2, 5):
        out[a] = min(halves[0, a], halves[1, a])
        out[a + 3] = max(halves[0, a + 3], halves[1, a + 3])
    return out


@numba.njit(cache=True)
def voxel_cells(points: np.ndarray, voxel: float, lo: np.ndarray) -> np.ndarray:
    """[3 N] int32 cells floor(p / voxel) - lo + CELL_MARGIN, x y z of each point in turn."""
    out = np.empty(3 * points.shape[0], dtype=np.int32)
    _cells_of_range(points, voxel, lo, ZERO, np.int64(points.shape[0]), out)
    return out


@numba.njit(cache=True, error_model="numpy")
def _cells_of_range(
    points: np.ndarray,
    voxel: float,
    lo: np.ndarray,
    start: int | np.int64,
    stop: int | np.int64,
    out: np.ndarray,
) -> None:
    """Cells of points[start:stop] into out[3 start : 3 stop] (see `voxel_cells`).

    Flat arrays: the loop vectorises (the divisions four at a time), which [N, 3] indexing
    does not. Exact: floor(p / voxel) and lo are integers in float64, their difference small.
    """
    flat = points.reshape(-1)[3 * start : 3 * stop]  # from 0: the loop then vectorises
    cells = out[3 * start : 3 * stop]
    sx = float(lo[0] - CELL_MARGIN)
    sy = float(lo[1] - CELL_MARGIN)
    sz = float(lo[2] - CELL_MARGIN)
    for i in range(stop - start):
        cells[3 * i] = np.int32(np.floor(flat[3 * i] / voxel) - sx)
        cells[3 * i + 1] = np.int32(np.floor(flat[3 * i + 1] / voxel) - sy)
        cells[3 * i + 2] = np.int32(np.floor(flat[3 * i + 2] / voxel) - sz)


@numba.njit(cache=True)
def _voxelize_until_full(
    cells: np.ndarray,
    start: int,
    state: np.ndarray,
    table_keys: np.ndarray,
    table_ids: np.ndarray,
    keys: np.ndarray,
    slot_voxel: np.ndarray,
    point_voxel: np.ndarray,
    voxel_block: np.ndarray,
    voxel_slot: np.ndarray,
) -> int:
    """Voxelize points from `start` until a new block would overfill the table or the
    block store (`keys`, `slot_voxel`).

    `state` = (n_blocks, n_voxels, last block key, its block) is updated in place.
    Returns the index of the first point not processed.
    """
    cap = table_keys.shape[0]
    n_blocks, n_voxels, last_key, b = state[0], state[1], state[2], state[3]
    i = start
    while i < point_voxel.shape[0]:
        cx, cy, cz = int(cells[3 * i]), int(cells[3 * i + 1]), int(cells[3 * i + 2])
        k = block_key(cx, cy, cz)
        if k != last_key:
            h = hash_slot(k, cap - 1)
            while True:
                tk = table_keys[h]
                if tk == k:
                    b = table_ids[h]
                    break
                if tk == -1:
                    if 2 * (n_blocks + 1) > cap or n_blocks == keys.shape[0]:
                        state[0], state[1], state[2], state[3] = n_blocks, n_voxels, last_key, b
                        return i
                    table_keys[h] = k
                    table_ids[h] = n_blocks
                    keys[n_blocks] = k
                    slot_voxel[n_blocks * SLOTS : (n_blocks + 1) * SLOTS] = -1
                    b = n_blocks
                    n_blocks += 1
                    break
                h = (h + 1) & (cap - 1)
            last_key = k
        s = slot_of(cx, cy, cz)
        flat = b * SLOTS + s
        v = slot_voxel[flat]
        if v < 0:
            v = n_voxels
            slot_voxel[flat] = v
            voxel_block[v] = b
            voxel_slot[v] = s
            n_voxels += 1
        point_voxel[i] = v
        i += 1
    state[0], state[1], state[2], state[3] = n_blocks, n_voxels, last_key, b
    return i


@numba.njit(cache=True)
def _grown(values: np.ndarray, size: int, fill: int) -> np.ndarray:
    """A copy of 1-D `values` padded with `fill` to `size` entries."""
    out = np.empty(size, dtype=values.dtype)
    for i in range(values.shape[0]):
        out[i] = values[i]
    for i in range(values.shape[0], size):
        out[i] = fill
    return out


@numba.njit(cache=True)
def _rehash(keys: np.ndarray, n_keys: int, cap: int) -> tuple[np.ndarray, np.ndarray]:
    """A fresh open-addressing table of `cap` slots holding keys[:n_keys] -> their index."""
    table_keys = np.full(cap, -1, dtype=np.int64)
    table_ids = np.zeros(cap, dtype=np.int32)
    for q in range(n_keys):
        h = hash_slot(keys[q], cap - 1)
        while table_keys[h] != -1:
            h = (h + 1) & (cap - 1)
        table_keys[h] = keys[q]
        table_ids[h] = q
    return table_keys, table_ids


@numba.njit(cache=True)
def _table_capacity(n: int) -> int:
    """Hash table slots for n points: a power of two >= n / 8, at least 1024."""
    cap = 1024
    while cap < n // 8:
        cap *= 2
    return cap


@numba.njit(cache=True)
def _block_room(n: int) -> int:
    """Blocks the store first holds for n points (it doubles when full): a frame has ~100
    points per block, and a store much larger than its blocks is memory the allocator hands
    back and faults in again on the next fit."""
    return n // BLOCK_ROOM_DIVISOR + 16


@numba.njit(cache=True)
def _empty_store(n: int) -> tuple:
    """An empty table and block store for n points, and room for their voxels: (table keys,
    table ids, block keys, voxel in each block slot, block and slot of each voxel). A
    block's slots are set to -1 when the block is created: no memset of the whole store."""
    table_keys, table_ids = _rehash(np.empty(0, dtype=np.int64), ZERO, _table_capacity(n))
    keys = np.empty(_block_room(n), dtype=np.int64)
    slot_voxel = np.empty(keys.shape[0] * SLOTS, dtype=np.int32)
    voxel_block = np.empty(n, dtype=np.int32)
    voxel_slot = np.empty(n, dtype=np.int32)
    return table_keys, table_ids, keys, slot_voxel, voxel_block, voxel_slot


@numba.njit(cache=True)
def _voxelised(point_voxel: np.ndarray, n_blocks: int, n_voxels: int, store: tuple) -> tuple:
    """`voxelize`'s outputs from a filled store of n_blocks blocks and n_voxels voxels."""
    table_keys, table_ids, keys, slot_voxel, voxel_block, voxel_slot = store
    return (
        point_voxel,
        slot_voxel[: n_blocks * SLOTS],
        voxel_block[:n_voxels],
        voxel_slot[:n_voxels],
        keys[:n_blocks],
        table_keys,
        table_ids,
    )


@numba.njit(cache=True)
def _room_for_a_block(
    n_blocks: int,
    table_keys: np.ndarray,
    table_ids: np.ndarray,
    keys: np.ndarray,
    slot_voxel: np.ndarray,
) -> tuple:
    """The table (rehashed at twice the slots) or the block store (twice the blocks), grown
    so that one more block fits: (table keys, table ids, keys, slot_voxel)."""
    if n_blocks == keys.shape[0]:
        keys = _grown(keys, 2 * keys.shape[0], 0)
        slot_voxel = _grown(slot_voxel, keys.shape[0] * SLOTS, -1)
    if 2 * (n_blocks + 1) > table_keys.shape[0]:
        table_keys, table_ids = _rehash(keys, n_blocks, 2 * table_keys.shape[0])
    return table_keys, table_ids, keys, slot_voxel


@numba.njit(cache=True)
def _voxelize_rest(
    cells: np.ndarray,
    start: int,
    state: np.ndarray,
    table_keys: np.ndarray,
    table_ids: np.ndarray,
    keys: np.ndarray,
    slot_voxel: np.ndarray,
    point_voxel: np.ndarray,
    voxel_block: np.ndarray,
    voxel_slot: np.ndarray,
) -> tuple:
    """`_voxelize_until_full` from `start` to the last point, growing the table and the
    block store when full; returns (table keys, table ids, keys, slot_voxel)."""
    i = start
    while True:
        i = _voxelize_until_full(
            cells, i, state, table_keys, table_ids, keys, slot_voxel,
            point_voxel, voxel_block, voxel_slot,
        )  # fmt: skip
        if i == point_voxel.shape[0]:
            return table_keys, table_ids, keys, slot_voxel
        table_keys, table_ids, keys, slot_voxel = _room_for_a_block(
            state[0], table_keys, table_ids, keys, slot_voxel
        )


@numba.njit(cache=True)
def voxelize(points: np.ndarray, voxel: float, lo: np.ndarray) -> tuple:
    """Number the blocks and occupied voxels of a cloud in first-seen order, in one pass.

    Voxel cell coordinates are floor(p / voxel) - lo + CELL_MARGIN.

    Returns:
        (voxel of each point [N], voxel in each block slot [B * 64] (-1 = empty),
         block [V] and slot [V] of each voxel, block keys [B], hash table keys, table ids).
    """
    n = points.shape[0]
    table_keys, table_ids, keys, slot_voxel, voxel_block, voxel_slot = _empty_store(n)
    cells = voxel_cells(points, voxel, lo)
    point_voxel = np.empty(n, dtype=np.int32)
    state = np.array([0, 0, -1, -1], dtype=np.int64)
    table_keys, table_ids, keys, slot_voxel = _voxelize_rest(
        cells, ZERO, state, table_keys, table_ids, keys, slot_voxel,
        point_voxel, voxel_block, voxel_slot,
    )  # fmt: skip
    return _voxelised(
        point_voxel, state[0], state[1],
        (table_keys, table_ids, keys, slot_voxel, voxel_block, voxel_slot),
    )  # fmt: skip


@numba.njit(cache=True)
def _voxelize_half(
    k: np.int64,  # int64 in both of the parfor's typings (one types k uint64): one compile
    points: np.ndarray,
    voxel: float,
    lo: np.ndarray,
    half: int,
    cells: np.ndarray,
    point_voxel: np.ndarray,
    states: np.ndarray,
    stops: np.ndarray,
    a: tuple,
    b: tuple,
) -> None:
    """Half k of `voxelize_halves`: its cells, then its voxels until its table is full."""
    start, stop = (ZERO, np.int64(half)) if k == 0 else (np.int64(half), np.int64(points.shape[0]))
    _cells_of_range(points, voxel, lo, start, stop, cells)
    table_keys, table_ids, keys, slot_voxel, voxel_block, voxel_slot = a if k == 0 else b
    stops[k] = _voxelize_until_full(
        cells[3 * start : 3 * stop], ZERO, states[k], table_keys, table_ids, keys, slot_voxel,
        point_voxel[start:stop], voxel_block, voxel_slot,
    )  # fmt: skip


@numba.njit(cache=True, parallel=True)
def _voxelize_halves_parallel(
    points: np.ndarray,
    voxel: float,
    lo: np.ndarray,
    half: int,
    cells: np.ndarray,
    point_voxel: np.ndarray,
    states: np.ndarray,
    stops: np.ndarray,
    a: tuple,
    b: tuple,
) -> None:
    for k in numba.prange(2):  # nothing else here: array code would spawn parfors
        _voxelize_half(
            np.int64(k), points, voxel, lo, half, cells, point_voxel, states, stops, a, b
        )


@numba.njit(cache=True)
def voxelize_halves(points: np.ndarray, voxel: float, lo: np.ndarray) -> tuple:
    """`voxelize` with the two halves of the points hashed on two threads: the same outputs.

    The first half numbers its blocks and voxels in the final table; the second numbers its
    own, which then join the first's in their first-seen order (so a block or voxel first
    seen in the second half gets the number `voxelize` gives it), and its points take the
    joined numbers.

    Returns:
        `voxelize`'s outputs, then the number of voxels first seen in the first half (the
        voxels numbered from it on hold points of the second half only).
    """
    n = points.shape[0]
    half = n // 2
    a = _empty_store(n)  # sized for the whole cloud: the second half's blocks join it
    b = _empty_store(n - half)
    cells = np.empty(3 * n, dtype=np.int32)
    point_voxel = np.empty(n, dtype=np.int32)
    states = np.empty((2, 4), dtype=np.int64)
    states[:, 0] = 0
    states[:, 1] = 0
    states[:, 2] = -1
    states[:, 3] = -1
    stops = np.empty(2, dtype=np.int64)
    _voxelize_halves_parallel(points, voxel, lo, half, cells, point_voxel, states, stops, a, b)
    # A half whose table filled goes on here, growing it as `voxelize` does.
    a_table_keys, a_table_ids, a_keys, a_slot_voxel, voxel_block, voxel_slot = a
    a_table_keys, a_table_ids, a_keys, a_slot_voxel = _voxelize_rest(
        cells[: 3 * half], stops[0], states[0], a_table_keys, a_table_ids, a_keys,
        a_slot_voxel, point_voxel[:half], voxel_block, voxel_slot,
    )  # fmt: skip
    b_table_keys, b_table_ids, b_keys, b_slot_voxel, b_voxel_block, b_voxel_slot = b
    b_keys = _voxelize_rest(
        cells[3 * half :], stops[1], states[1], b_table_keys, b_table_ids, b_keys,
        b_slot_voxel, point_voxel[half:], b_voxel_block, b_voxel_slot,
    )[2]  # fmt: skip
    # The second half's blocks, then its voxels, join the first's in first-seen order.
    first_half_voxels = states[0, 1]
    a_table_keys, a_table_ids, a_keys, a_slot_voxel, n_blocks, n_voxels = _join_second_half(
        states, a_table_keys, a_table_ids, a_keys, a_slot_voxel, voxel_block, voxel_slot,
        b_keys, b_voxel_block, b_voxel_slot, point_voxel, half,
    )  # fmt: skip
    store = (a_table_keys, a_table_ids, a_keys, a_slot_voxel, voxel_block, voxel_slot)
    return (*_voxelised(point_voxel, n_blocks, n_voxels, store), first_half_voxels)


@numba.njit(cache=True)
def _join_second_half(
    states: np.ndarray,
    a_table_keys: np.ndarray,
    a_table_ids: np.ndarray,
    a_keys: np.ndarray,
    a_slot_voxel: np.ndarray,
    voxel_block: np.ndarray,
    voxel_slot: np.ndarray,
    b_keys: np.ndarray,
    b_voxel_block: np.ndarray,
    b_voxel_slot: np.ndarray,
    point_voxel: np.ndarray,
    half: int,
) -> tuple:
    """The second half's blocks, then its voxels, numbered after the first half's in their
    first-seen order, and its points' voxels renumbered; returns the first half's table,
    keys and slot store (grown as `voxelize` grows them) and the block and voxel counts."""
    n_blocks, n_voxels = states[0, 0], states[0, 1]
    block_map = np.empty(states[1, 0], dtype=np.int32)
    for q in range(states[1, 0]):
        key = b_keys[q]
        if 2 * (n_blocks + 1) > a_table_keys.shape[0] or n_blocks == a_keys.shape[0]:
            a_table_keys, a_table_ids, a_keys, a_slot_voxel = _room_for_a_block(
                n_blocks, a_table_keys, a_table_ids, a_keys, a_slot_voxel
            )
        mask = a_table_keys.shape[0] - 1
        h = hash_slot(key, mask)
        while True:
            tk = a_table_keys[h]
            if tk == key:
                block_map[q] = a_table_ids[h]
                break
            if tk == -1:
                a_table_keys[h] = key
                a_table_ids[h] = n_blocks
                a_keys[n_blocks] = key
                a_slot_voxel[n_blocks * SLOTS : (n_blocks + 1) * SLOTS] = -1
                block_map[q] = n_blocks
                n_blocks += 1
                break
            h = (h + 1) & mask
    voxel_map = np.empty(states[1, 1], dtype=np.int32)
    for u in range(states[1, 1]):
        g = block_map[b_voxel_block[u]]
        s = b_voxel_slot[u]
        flat = g * SLOTS + s
        v = a_slot_voxel[flat]
        if v < 0:
            v = n_voxels
            a_slot_voxel[flat] = v
            voxel_block[v] = g
            voxel_slot[v] = s
            n_voxels += 1
        voxel_map[u] = v
    for i in range(half, point_voxel.shape[0]):
        point_voxel[i] = voxel_map[point_voxel[i]]
    return a_table_keys, a_table_ids, a_keys, a_slot_voxel, n_blocks, n_voxels
