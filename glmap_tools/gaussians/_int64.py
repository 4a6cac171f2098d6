"""`ZERO`, the int64 0 that kernels pass to one another where a literal 0 would do.

numba compiles a function called from a kernel once per argument type, and a literal has a
type of its own (`Literal[int](0)`): a range function called with 0 by the serial path and
with a computed bound by the thread team's chunks compiled twice (gaussians/design.md,
Compile time). A global numpy int64 is typed int64; the type checker reads it as an int.
"""

from typing import cast

import numpy as np

ZERO = cast(int, np.int64(0))
