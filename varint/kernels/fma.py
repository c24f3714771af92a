"""A fused multiply–add for compiled kernels: ``fma(a, b, c)`` = a·b + c
with one rounding, LLVM's ``llvm.fma`` intrinsic (one instruction on every
x86-64 CPU with FMA3 and on ARMv8; elsewhere a call to the C library's
``fma``, as exact and slower).

The generated steppers (:mod:`varint.codegen`) write their drifts
and kicks with it. A step is a chain of dependent multiply–adds, and the
fused ones halve its latency (the Hénon–Heiles orbit under ABA864: 43 →
35 ns per step, as fast as gcc -O3's loop of the same stages, which
contracts them on its own). Written out rather than left to the compiler
(numba's ``fastmath={'contract'}``), the fusion is the same in the scalar
one-orbit stepper, in the vectorised body of the SIMD lanes and in their
scalar remainder, so the lanes stay bitwise the one-orbit stepper.
"""

from __future__ import annotations

from numba import types
from numba.core.extending import intrinsic

__all__ = ["fma"]


@intrinsic
def fma(typingctx, a, b, c):
    """a·b + c, rounded once (float64 arguments)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen
