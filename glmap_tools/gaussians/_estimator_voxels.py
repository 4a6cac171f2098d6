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


@numba.njit(cache=True, error_model="numpy")
def voxel_cells(points: np.ndarray, voxel: float, lo: np.ndarray) -> np.ndarray:
    """[3 N] int32 cells floor(p / voxel) - lo + CELL_MARGIN, x y z of each point in turn.

    Flat arrays: the loop vectorises (the divisions four at a time), which [N, 3] indexing
    does not. Exact: floor(p / voxel) and lo are integers in float64, their difference small.
    """
    flat = points.reshape(-1)
    out = np.empty(flat.shape[0], dtype=np.int32)
    sx = float(lo[0] - CELL_MARGIN)
    sy = float(lo[1] - CELL_MARGIN)
    sz = float(lo[2] - CELL_MARGIN)
    for i in range(points.shape[0]):
        out[3 * i] = np.int32(np.floor(flat[3 * i] / voxel) - sx)
        out[3 * i + 1] = np.int32(np.floor(flat[3 * i + 1] / voxel) - sy)
        out[3 * i + 2] = np.int32(np.floor(flat[3 * i + 2] / voxel) - sz)
    return out


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
    """Voxelize points from `start` until a new block would overfill the table.

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
                    if 2 * (n_blocks + 1) > cap:
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
def voxelize(points: np.ndarray, voxel: float, lo: np.ndarray) -> tuple:
    """Number the blocks and occupied voxels of a cloud in first-seen order, in one pass.

    Voxel cell coordinates are floor(p / voxel) - lo + CELL_MARGIN.

    Returns:
        (voxel of each point [N], voxel in each block slot [B * 64] (-1 = empty),
         block [V] and slot [V] of each voxel, block keys [B], hash table keys, table ids).
    """
    n = points.shape[0]
    cap = 1024
    while cap < n // 8:
        cap *= 2
    table_keys, table_ids = _rehash(np.empty(0, dtype=np.int64), ZERO, cap)
    cells = voxel_cells(points, voxel, lo)
    keys = np.empty(cap // 2, dtype=np.int64)
    # A block's slots are set to -1 when the block is created: no memset of the whole store.
    slot_voxel = np.empty((cap // 2) * SLOTS, dtype=np.int32)
    point_voxel = np.empty(n, dtype=np.int32)
    voxel_block = np.empty(n, dtype=np.int32)
    voxel_slot = np.empty(n, dtype=np.int32)
    state = np.array([0, 0, -1, -1], dtype=np.int64)
    i = ZERO
    while True:
        i = _voxelize_until_full(
            cells, i, state, table_keys, table_ids, keys, slot_voxel,
            point_voxel, voxel_block, voxel_slot,
        )  # fmt: skip
        if i == n:
            break
        cap *= 2  # grow the table and the block storage, rehash
        keys = _grown(keys, cap // 2, 0)
        slot_voxel = _grown(slot_voxel, (cap // 2) * SLOTS, -1)
        table_keys, table_ids = _rehash(keys, state[0], cap)
    n_blocks, n_voxels = state[0], state[1]
    return (
        point_voxel,
        slot_voxel[: n_blocks * SLOTS],
        voxel_block[:n_voxels],
        voxel_slot[:n_voxels],
        keys[:n_blocks],
        table_keys,
        table_ids,
    )
