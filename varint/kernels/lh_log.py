"""The natural logarithm of the generated LH steppers: ``lane_log``, the
bits of :func:`varint.kernels.logarithm.vlog` without a branch, so that a
loop over SIMD lanes that takes it vectorises.

Why. A potential with a logarithm (the cored logarithmic potential
V = ½ ln(R_c² + x² + y²/q²)) takes one per kick. Printed as ``math.log``
(the C library's), the LH lanes (:mod:`varint.codegen.lh_lanes`) ran V
and ∇V in a scalar loop of their own over the lanes, its results passed
on in rows: LLVM vectorises no loop that calls the C library. ``vlog``
(fdlibm's algorithm, written out) is arithmetic and bit casts only, but its
early returns (zero, negative, subnormal and non-finite arguments, |f| <
2⁻²⁰, two formulas for the two halves of the reduced interval) leave LLVM
a branching body it did not vectorise either. ``lane_log`` computes every
case and selects the one ``vlog`` returns: the same operations on the same
values, hence the same bits (``tests/test_lh_log.py`` compares them over
every binade, subnormals, the neighbourhood of 1 and the special values),
within 1 ulp of the correctly rounded logarithm (0.79 ulp measured,
``tests/test_logarithm.py``), where the C library's is within 0.51: a
generated LH stepper's V may differ from the C library's in the last place.

Two rewritings keep it a select, not a branch, and change no bit:

* where ``vlog`` returns ``f - r`` or ``f - (hfsq - s (hfsq + r))`` for
  k = 0, ``lane_log`` takes the general k ln 2 formula at k = 0: with
  k ln 2 = +0 and the zero terms, ``0 − ((a − 0) − f)`` is ``f − a``
  exactly (IEEE negation and subtraction of zero are exact; x = 1 gives +0
  either way); at f = 0 the |f| < 2⁻²⁰ formula is k ln2_hi + k ln2_lo
  exactly, as ``vlog``'s;
* k, a small integer, becomes a double by the exponent trick (its bits
  added to those of 2⁵² and 2⁵² subtracted, exact for |k| < 2⁵¹): AVX2 has
  no vector conversion of 64-bit integers.
"""

from __future__ import annotations

import math

from numba import njit, types
from numba.core.extending import intrinsic

from .fma import fma
from .logarithm import as_bits, from_bits

__all__ = ["lane_log"]


@intrinsic
def pick(typingctx, cond, a, b):
    """``a if cond else b`` as one LLVM ``select`` (both computed, no branch),
    for ``a`` and ``b`` of one type."""
    if not isinstance(cond, types.Boolean) or a != b:
        return None

    def codegen(context, builder, signature, args):
        return builder.select(*args)

    return a(cond, a, b), codegen


@njit(inline="always", error_model="numpy")
def lane_log(x):
    """Natural logarithm with the bits of :func:`varint.kernels.logarithm.vlog`
    (fdlibm's ``__ieee754_log``), every case computed and one selected
    (module docstring)."""
    ix = as_bits(x)
    # Zero, negative or subnormal: the subnormal scaled by 2**54, exactly.
    tiny = ix < 0x0010000000000000
    y = pick(tiny, x * 18014398509481984.0, x)
    k = pick(tiny, -54, 0)
    iy = as_bits(y)
    # The high word (the mask makes the shift logical: AVX2 shifts 64-bit
    # lanes logically only).
    hx = (iy >> 32) & 0x7FFFFFFF
    k += (hx >> 20) - 1023
    hx &= 0xFFFFF
    i = (hx + 0x95F64) & 0x100000
    # y or y/2 (the exponent set to 0 or -1): 1 + f in [sqrt(2)/2, sqrt(2)).
    z = from_bits(((hx | (i ^ 0x3FF00000)) << 32) | (iy & 0xFFFFFFFF))
    k += i >> 20
    f = z - 1.0
    dk = from_bits(0x4330000000000000 + (k + 4096)) - 4503599627374592.0
    hi = dk * 6.93147180369123816490e-01
    lo = dk * 1.90821492927058770002e-10
    s = f / (2.0 + f)
    zz = s * s
    w = zz * zz
    t1 = w * fma(w, fma(w, 1.531383769920937332e-01, 2.222219843214978396e-01),
                 3.999999999940941908e-01)
    t2 = zz * fma(w, fma(w, fma(w, 1.479819860511658591e-01, 1.818357216161805012e-01),
                         2.857142874366239149e-01), 6.666666666666735130e-01)
    r = t2 + t1
    hfsq = 0.5 * f * f
    out = pick(((hx - 0x6147A) | (0x6B851 - hx)) > 0,
               hi - ((hfsq - (s * (hfsq + r) + lo)) - f), hi - ((s * (f - r) - lo) - f))
    # |f| < 2**-20.
    out = pick(((2 + hx) & 0xFFFFF) < 3,
               hi - ((f * f * (0.5 - 0.33333333333333333 * f) - lo) - f), out)
    out = pick(ix >= 0x7FF0000000000000, x + x, out)
    out = pick(ix < 0, math.nan, out)
    return pick((ix & 0x7FFFFFFFFFFFFFFF) == 0, -math.inf, out)
