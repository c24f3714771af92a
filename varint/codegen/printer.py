"""How the generated steppers print their SymPy expressions: the model
kernels' printer (:class:`~varint.models.symbolic.KernelPrinter`) with two
rules more, half-integer powers as products and a square root, and
negative integer powers as one over the positive power.

The derivatives of a point mass or a softened one (the three-body problem,
Plummer spheres, Keplerian potentials, a bar's disc and bulge) hold
b^(p/2) with p odd: r⁻³ = (r²)^(−3/2), r⁻⁵ = (r²)^(−5/2). SymPy prints
them as ``b**(3/2)``, which numba compiles to a call of ``pow``, ≈ 61
additions against ≈ 6 for a square root (``studies/results/step_cost.json``);
in a constant-step SRKN14a step of the three-body problem the 84 calls
were most of its time. :class:`StepperPrinter` writes b^(p/2), |p| ≥ 3, as
``b * … * math.sqrt(b)`` with (|p| − 1)/2 factors b, and b^(−p/2) as one
over it; LLVM computes a square root common to several powers once.
Exponents ±1/2 are SymPy's own ``math.sqrt(b)`` and ``1/math.sqrt(b)``;
positive integer powers stay ``b**k``, which numba writes as
multiplications (``numba.cpython.numbers.static_power_impl``: binary
powering), so a model without half-integer or negative powers gets the
same source, hence the same bits.

A negative integer power b^(−k), k ≥ 2, which SymPy prints alone as
``b**(-k)`` (inside a product it is already a denominator), is printed
``(1.0 / b**k)``. numba computes ``b**(-k)`` as the same product and one
division, but compiles that division under Python's error model whatever
the kernel's (a test for a zero divisor that raises): the branch keeps
LLVM from vectorising a loop over SIMD lanes around it. The cored
logarithmic potential's Hessian holds (R_c² + x² + y²/q²)^(−2) in every
kick, so its lanes ran one at a time in scalar code
(``studies/switch_check.py``). Written as a division, the loop vectorises
and every value is the same bits (the same product, the same correctly
rounded division; ``tests/test_printer.py``); only b^k = 0 (b = 0, or
b^k underflowing: |b| < 1.6e-162 for k = 2) differs: ±inf, as ``pow``
gives, where numba raised ``ZeroDivisionError`` out of the kernel. The
derivatives' finiteness checks see the infinity as any non-finite value.

What changes, and what does not (``tests/test_printer.py``):

* the value: one correctly rounded square root and (|p| − 1)/2 roundings
  of products (one more for the division), against ``pow``'s one: within
  (|p| + 3)/2 units in the last place of it, where the result is a normal
  number;
* a finite b < 0 or NaN gives NaN, b = +0 gives 0 (p > 0) or +inf
  (p < 0), b = +inf gives inf or 0, as ``pow``; at b = −0 (which a sum of
  squares never is) the product's zero or infinity may take the other
  sign — the finiteness checks of the derivatives see a non-finite value
  either way; b = −inf gives NaN where ``pow`` gives inf or 0 (a base
  gets there only by overflowing past the negative ones, where both are
  NaN already);
* overflow: for p > 0 and b > 1 every partial product is smaller than the
  result, so the product overflows where ``pow`` does. For p < 0 a huge b
  makes the denominator overflow and the power 0 where ``pow`` returns a
  subnormal number (below 2.3e−308; r⁻⁵ beyond r ≈ 3e61, r⁻⁷ of a
  corrector's D²C beyond r ≈ 1e44, where a derivative that multiplies it
  by powers of q loses that term: the orbit is far beyond any bound
  orbit's), and a tiny b makes it a subnormal number, whose lost digits
  cost one or two ulp of a result near the largest double. No finite
  derivative becomes non-finite, nor the reverse, except within a few ulp
  of the overflow threshold (``tests/test_printer.py`` checks the
  three-body problem's ∇V and D²V at the primaries, at subnormal and at
  overflowing distances).
"""

from __future__ import annotations

from sympy.printing.precedence import precedence

from ..models.symbolic import KernelPrinter

__all__ = ["StepperPrinter"]


class StepperPrinter(KernelPrinter):
    """:class:`~varint.models.symbolic.KernelPrinter` with b^(p/2), p odd,
    |p| ≥ 3, written as ``((b) * … * math.sqrt(b))`` and its reciprocal for
    p < 0 instead of ``b**(p/2)``, and b^(−k), k ≥ 2, as ``(1.0 / b**k)``
    instead of ``b**(-k)`` (module docstring).

    >>> import sympy as sp
    >>> x = sp.Symbol("x")
    >>> StepperPrinter().doprint(3 * x**sp.Rational(-5, 2))
    '3/((x) * (x) * math.sqrt(x))'
    >>> StepperPrinter().doprint((1 + x**2)**-2)
    '(1.0 / (x**2 + 1)**2)'
    """

    def _print_Pow(self, expr, rational=False):
        e = expr.exp
        if e.is_Integer and int(e) <= -2:
            # numba's own b**(-k) is the same product and a division that
            # tests for a zero divisor (its error model, not the kernel's):
            # that test keeps a loop over lanes from vectorising.
            base = self.parenthesize(expr.base, precedence(expr))
            return f"(1.0 / {base}**{-int(e)})"
        if not (e.is_Rational and e.q == 2 and abs(e.p) >= 3):
            return super()._print_Pow(expr, rational=rational)
        base = f"({self._print(expr.base)})"
        product = " * ".join([base] * ((abs(e.p) - 1) // 2) + [f"math.sqrt{base}"])
        return f"({product})" if e.p > 0 else f"(1.0 / ({product}))"
