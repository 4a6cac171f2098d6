"""Layout of the per-Gaussian screen parameters the projection writes and the rasterizer reads.

One 64-byte float32 row per Gaussian (`N_PARAMS` columns). DU, DV: the screen mean minus the
footprint rectangle's first column and row (small numbers, so float32 keeps them to ~1e-7 of
the footprint size). OPACITY is negated for a thin footprint (see SPAN_*); a compact one
keeps d^T conic d below M_COMPACT over its whole rectangle, which is then walked whole.
DECAY_X, DECAY_Y, DECAY_XY = exp(-ca), exp(-cc), exp(-cb) step exp(-m/2) across pixels;
each is stored as a float32 pair (value, remainder) that sums to the float64, as the
recurrences multiply them up to a tile side of times.
"""

from __future__ import annotations

(DU, DV, CONIC_A, CONIC_B, CONIC_C, OPACITY) = range(6)
(DECAY_X, DECAY_X_LO, DECAY_Y, DECAY_Y_LO, DECAY_XY, DECAY_XY_LO) = range(6, 12)
RED, GREEN, BLUE, DEPTH = range(12, 16)
N_PARAMS = 16
# Columns of the thin footprints' row spans (float32, unset for compact ones): on pixel row
# y the footprint is the column interval centre(y) +- sqrt(SPAN_HALF0 - SPAN_HALF1 dy^2)
# where the alpha can reach ALPHA_MIN, centre(y) = u - SPAN_SLOPE dy.
SPAN_HALF0, SPAN_HALF1, SPAN_SLOPE = range(3)
N_SPAN = 3
M_COMPACT = 200.0  # exp(-m/2) by forward differences stays far from under/overflow below this
PAD = 1e-6  # px slack on the footprint rectangle; the exact alpha test decides inside it
ROW_PAD = 1e-3  # px slack on the row spans, wider than the float32 rounding of their terms
