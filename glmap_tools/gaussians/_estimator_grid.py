"""A sparse block grid for numba: 4x4x4 cells per block, blocks found by hashing.

Cell coordinates are non-negative int64 with a margin of one block on each side. A block
key packs the block coordinates 21 bits each; blocks are numbered in first-seen order and
own 64 dense slots, so neighbour cells are found by array arithmetic plus a per-block table
of its 27 neighbour blocks, with no hashing per cell.
"""

from __future__ import annotations

import numba
import numpy as np

BLOCK_SHIFT = 2  # 4 cells per block edge
BLOCK_MASK = 3
SLOTS = 64
KEY_SHIFT_X = 42
KEY_SHIFT_Y = 21
HASH_MULTIPLIER = -7046029254386353131  # 0x9E3779B97F4A7C15 as int64 (Fibonacci hashing)


@numba.njit(cache=True)
def hash_slot(key: int, mask: int) -> int:
    """Open-addressing start slot of a non-negative key."""
    h = key * HASH_MULTIPLIER
    return (h ^ (h >> 29)) & mask


@numba.njit(cache=True)
def block_key(cx: int, cy: int, cz: int) -> int:
    """Packed key of the block holding cell (cx, cy, cz)."""
    return (
        ((cx >> BLOCK_SHIFT) << KEY_SHIFT_X)
        | ((cy >> BLOCK_SHIFT) << KEY_SHIFT_Y)
        | (cz >> BLOCK_SHIFT)
    )


@numba.njit(cache=True)
def slot_of(cx: int, cy: int, cz: int) -> int:
    """Index of cell (cx, cy, cz) among its block's 64 slots."""
    return ((cx & BLOCK_MASK) << 4) | ((cy & BLOCK_MASK) << 2) | (cz & BLOCK_MASK)


@numba.njit(cache=True)
def find_block(table_keys: np.ndarray, table_ids: np.ndarray, key: int) -> int:
    """Block number of `key`, or -1."""
    mask = table_keys.shape[0] - 1
    h = hash_slot(key, mask)
    while True:
        tk = table_keys[h]
        if tk == key:
            return table_ids[h]
        if tk == -1:
            return -1
        h = (h + 1) & mask


@numba.njit(cache=True)
def blocks_of(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Number the blocks of [M, 3] cell coordinates in first-seen order.

    Returns:
        (block [M] of each cell, block keys [B], hash table keys [C], table ids [C]).
    """
    m = cells.shape[0]
    runs = 1
    for i in range(1, m):
        if block_key(cells[i, 0], cells[i, 1], cells[i, 2]) != block_key(
            cells[i - 1, 0], cells[i - 1, 1], cells[i - 1, 2]
        ):
            runs += 1
    cap = 16
    while cap < 2 * runs:
        cap *= 2
    mask = cap - 1
    table_keys = np.full(cap, -1, dtype=np.int64)
    table_ids = np.zeros(cap, dtype=np.int64)
    keys = np.empty(runs, dtype=np.int64)
    block = np.empty(m, dtype=np.int64)
    n_blocks = 0
    last_key = -1
    last_block = -1
    for i in range(m):
        k = block_key(cells[i, 0], cells[i, 1], cells[i, 2])
        if k != last_key:
            h = hash_slot(k, mask)
            while True:
                tk = table_keys[h]
                if tk == k:
                    last_block = table_ids[h]
                    break
                if tk == -1:
                    table_keys[h] = k
                    table_ids[h] = n_blocks
                    keys[n_blocks] = k
                    last_block = n_blocks
                    n_blocks += 1
                    break
                h = (h + 1) & mask
            last_key = k
        block[i] = last_block
    return block, keys[:n_blocks], table_keys, table_ids


@numba.njit(cache=True)
def block_neighbours(keys: np.ndarray, table_keys: np.ndarray, table_ids: np.ndarray) -> np.ndarray:
    """[B, 27] block numbers of each block's Chebyshev-1 neighbours (-1 = absent)."""
    out = np.empty((keys.shape[0], 27), dtype=np.int64)
    for b in range(keys.shape[0]):
        k = 0
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    nk = keys[b] + (dx << KEY_SHIFT_X) + (dy << KEY_SHIFT_Y) + dz
                    out[b, k] = find_block(table_keys, table_ids, nk)
                    k += 1
    return out


@numba.njit(cache=True)
def neighbour_tables() -> tuple[np.ndarray, np.ndarray]:
    """[64, 27] neighbour-block code and neighbour slot of each (slot, offset code).

    Offset code k = (dx + 1) * 9 + (dy + 1) * 3 + (dz + 1); neighbour-block codes index
    the rows of `block_neighbours`.
    """
    codes = np.empty((SLOTS, 27), dtype=np.int64)
    slots = np.empty((SLOTS, 27), dtype=np.int64)
    for s in range(SLOTS):
        for k in range(27):
            x = (s >> 4) + k // 9 - 1
            y = ((s >> 2) & BLOCK_MASK) + (k // 3) % 3 - 1
            z = (s & BLOCK_MASK) + k % 3 - 1
            codes[s, k] = (
                ((x >> BLOCK_SHIFT) + 1) * 9
                + ((y >> BLOCK_SHIFT) + 1) * 3
                + ((z >> BLOCK_SHIFT) + 1)
            )
            slots[s, k] = ((x & BLOCK_MASK) << 4) | ((y & BLOCK_MASK) << 2) | (z & BLOCK_MASK)
    return codes, slots
