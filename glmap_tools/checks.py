"""Type predicates the input checks share: numbers that are not bools.

`numbers` knows numpy's scalars (np.int64 is Integral, np.float32 Real, np.bool_ neither),
so these hold for them without importing numpy (the server's launch path imports this)."""

from __future__ import annotations

import numbers
from typing import TypeGuard


def is_integer(value: object) -> TypeGuard[numbers.Integral]:
    """An integer (numpy's included), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def is_real(value: object) -> TypeGuard[numbers.Real]:
    """A real number (numpy's included), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)
