"""One natural logarithm for every target: ``vlog``, written out in Python.

The C library's ``log`` (CPU) and libdevice's ``__nv_log`` (CUDA) are both
faithful, not correctly rounded, and differ in the last place for some
arguments; a stepper that takes a logarithm (the sparse renormalisation
schedule, MEGNO's and FLI's accumulators) then gives other bits on a GPU
than on the CPU. ``vlog`` is one algorithm in source form (:data:`SOURCE`):
compiled by numba for the CPU (:func:`vlog`, which the generated CPU
steppers and compiled accumulator updates import) and written into the
generated CUDA kernels (:mod:`varint.gpu.emit`), so both do the same
operations, each correctly rounded (+, −, ×, ÷, fma): the same bits.

The algorithm is fdlibm's ``__ieee754_log`` (Sun Microsystems, 1993): x =
2^k (1 + f) with 1 + f in [√2/2, √2), found from x's bits (``as_bits``,
``from_bits``: a bit cast, :func:`as_bits` and :func:`from_bits` on the
CPU, libdevice's on a GPU), s = f / (2 + f), and log(1 + f) = f − s (f −
R(s²)) with R a minimax polynomial of degree 14 in s (error below
2^−58.45), evaluated here by Horner's rule with fused multiply–adds; k ln 2
with ln 2 split in two. Error below 1 ulp
(``tests/test_logarithm.py`` measures it against a correctly rounded log
over ~9400 arguments from every binade, subnormals and the neighbourhood of
1 included: at most 0.79 ulp, 96.5 % correctly rounded, where glibc's log
is within 0.51 ulp; so a run's logarithms may differ from the C library's
in the last place, the same on every target).

References
----------
Sun Microsystems, fdlibm 5.3, ``e_log.c`` (1993).
P. T. P. Tang, "Table-driven implementation of the logarithm function in
IEEE floating-point arithmetic", ACM TOMS 16 (1990) 378–400.
"""

from __future__ import annotations

import math

import struct

from numba import njit, types
from numba.core.extending import intrinsic

from .fma import fma

__all__ = ["SOURCE", "vlog", "as_bits", "from_bits", "py_as_bits", "py_from_bits"]

#: ``vlog(x)``: reads ``math``, ``fma`` (a correctly rounded fused
#: multiply–add), ``as_bits`` (float64 → its bits as an int64) and
#: ``from_bits`` (the inverse) from its module.
SOURCE = '''
def vlog(x):
    """Natural logarithm, < 1 ulp (fdlibm's algorithm, varint.kernels.logarithm)."""
    ix = as_bits(x)
    k = 0
    if ix < 0x0010000000000000:
        # Zero, negative, or subnormal (scaled by 2**54, exactly).
        if (ix & 0x7FFFFFFFFFFFFFFF) == 0:
            return -math.inf
        if ix < 0:
            return math.nan
        k = -54
        x = x * 18014398509481984.0
        ix = as_bits(x)
    if ix >= 0x7FF0000000000000:
        return x + x
    hx = ix >> 32
    k += (hx >> 20) - 1023
    hx &= 0xFFFFF
    i = (hx + 0x95F64) & 0x100000
    # x or x/2 (the exponent set to 0 or -1): 1 + f in [sqrt(2)/2, sqrt(2)).
    x = from_bits(((hx | (i ^ 0x3FF00000)) << 32) | (ix & 0xFFFFFFFF))
    k += i >> 20
    f = x - 1.0
    dk = float(k)
    if ((2 + hx) & 0xFFFFF) < 3:
        # |f| < 2**-20.
        if f == 0.0:
            return dk * 6.93147180369123816490e-01 + dk * 1.90821492927058770002e-10
        r = f * f * (0.5 - 0.33333333333333333 * f)
        if k == 0:
            return f - r
        return dk * 6.93147180369123816490e-01 - ((r - dk * 1.90821492927058770002e-10) - f)
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    t1 = w * fma(w, fma(w, 1.531383769920937332e-01, 2.222219843214978396e-01),
                 3.999999999940941908e-01)
    t2 = z * fma(w, fma(w, fma(w, 1.479819860511658591e-01, 1.818357216161805012e-01),
                        2.857142874366239149e-01), 6.666666666666735130e-01)
    r = t2 + t1
    if ((hx - 0x6147A) | (0x6B851 - hx)) > 0:
        hfsq = 0.5 * f * f
        if k == 0:
            return f - (hfsq - s * (hfsq + r))
        return dk * 6.93147180369123816490e-01 - (
            (hfsq - (s * (hfsq + r) + dk * 1.90821492927058770002e-10)) - f)
    if k == 0:
        return f - s * (f - r)
    return dk * 6.93147180369123816490e-01 - (
        (s * (f - r) - dk * 1.90821492927058770002e-10) - f)
'''


@intrinsic
def as_bits(typingctx, x):
    """The bits of float64 ``x`` as an int64 (a bit cast, no instruction)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.int64))

    return types.int64(types.float64), codegen


@intrinsic
def from_bits(typingctx, i):
    """The float64 whose bits are int64 ``i``."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.float64))

    return types.float64(types.int64), codegen


def py_as_bits(x):
    """:func:`as_bits` in Python (the CUDA simulator's)."""
    return struct.unpack("<q", struct.pack("<d", x))[0]


def py_from_bits(i):
    """:func:`from_bits` in Python (the CUDA simulator's)."""
    return struct.unpack("<d", struct.pack("<q", i))[0]


def _compiled(inline):
    scope = {"math": math, "fma": fma, "as_bits": as_bits, "from_bits": from_bits}
    exec(compile(SOURCE, "<varint.kernels.logarithm>", "exec"), scope)
    return njit(inline=inline, error_model="numpy")(scope["vlog"])


#: :data:`SOURCE` compiled for the CPU (inlined where it is called).
vlog = _compiled("always")
#: The same, called (numba compiles it once per process, LLVM may still
#: inline it): where the logarithm is off the hot path, numba's inlining of
#: its IR at every call site costs compile time for nothing (a generated
#: stepper's sparse schedule: its first process took 11.1 CPU s with it
#: inlined, 7.6 called, the same bits and speed; studies/stepper_compile.py).
vlog_called = _compiled("never")
