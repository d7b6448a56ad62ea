"""Explicit 4-wide vector operations for the pair gathers (numba intrinsics).

LLVM does not vectorise the gathers of :mod:`granpipe.engine.kernels` (the pair indices
are data, and numba leaves LLVM's SLP vectoriser off by default since it miscompiled
code: numba PR #8852, issues #8705 and #8681), so a scalar gather costs eight loads,
four subtractions and four stores per pair. With the per-disk records stored as four
consecutive doubles (``[x, y, vx, vy]``), :func:`sub4_rows` does one ``<4 x double>``
load from each disk and one subtraction (0.9 ns per pair on the drum pile alone; with
the copy into the records, the gather takes 1.7 instead of 2.0 ns per pair, and 2.7
instead of 4.3 with the tangent vector: ``benchmarks/engine_passes.py``). Lane by lane
the arithmetic is the IEEE arithmetic of the scalar code, so results are bit-identical.

Numba's on-disk cache keys a kernel on its own source file only: after editing this
module, delete ``src/granpipe/engine/__pycache__`` so that the kernels are recompiled.
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

__all__ = ["sub4_rows"]


@intrinsic
def sub4_rows(typingctx, dst, k, stride, src, i, j):
    """``dst[k + c*stride] = src[i + c] - src[j + c]`` for ``c = 0..3``: one 4-wide
    subtraction whose lanes are stored into four rows ``stride`` apart (a transpose of
    the record into struct-of-arrays rows, which the vectorised contact laws read).
    """
    for arg in (dst, src):
        if not (isinstance(arg, types.Array) and arg.ndim == 1 and arg.dtype == types.float64):
            return None
    sig = types.void(dst, k, stride, src, i, j)

    def codegen(context, builder, signature, args):
        dst_v, k_v, stride_v, src_v, i_v, j_v = args
        tys = signature.args
        d = context.make_array(tys[0])(context, builder, dst_v)
        s = context.make_array(tys[3])(context, builder, src_v)
        vptr = ir.VectorType(ir.DoubleType(), 4).as_pointer()

        def idx(val, ty):
            return context.cast(builder, val, ty, types.intp)

        a = builder.load(builder.bitcast(builder.gep(s.data, [idx(i_v, tys[4])]), vptr), align=8)
        b = builder.load(builder.bitcast(builder.gep(s.data, [idx(j_v, tys[5])]), vptr), align=8)
        diff = builder.fsub(a, b)
        pos = idx(k_v, tys[1])
        step = idx(stride_v, tys[2])
        for c in range(4):
            lane = builder.extract_element(diff, ir.Constant(ir.IntType(32), c))
            builder.store(lane, builder.gep(d.data, [pos]), align=8)
            pos = builder.add(pos, step)
        return context.get_dummy_value()

    return sig, codegen
