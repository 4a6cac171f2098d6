"""`prefetch_row(array, i)`: ask the CPU to start loading row i of a 2D array into cache.

A numba intrinsic around `llvm.prefetch` (read, high locality). It does nothing to the
program's results; the rasterizer uses it to fetch the parameters of the Gaussians a few
entries ahead in a tile's list, whose rows lie scattered in memory.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


def _prefetch_row(typingctx: Any, array: Any, row: Any) -> Any:
    """Prefetch the first element of array[row] (array: 2D numba array, row: integer)."""
    if not (isinstance(array, types.Array) and array.ndim == 2 and isinstance(row, types.Integer)):
        return None
    sig = types.void(array, row)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        array_type, row_type = signature.args
        arr = context.make_array(array_type)(context, builder, args[0])
        index = context.cast(builder, args[1], row_type, types.intp)
        zero = context.get_constant(types.intp, 0)
        ptr = cgutils.get_item_pointer2(
            context,
            builder,
            arr.data,
            cgutils.unpack_tuple(builder, arr.shape),
            cgutils.unpack_tuple(builder, arr.strides),
            array_type.layout,
            [index, zero],
            wraparound=False,
        )
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0i8")
        # (address, read = 0, locality = 3: keep in all cache levels, data cache = 1)
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return sig, codegen


# Typed for callers (numba calls the intrinsic as prefetch_row(array, row)).
prefetch_row = cast("Callable[[np.ndarray, int], None]", intrinsic(_prefetch_row))
