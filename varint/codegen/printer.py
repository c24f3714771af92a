"""How the generated steppers print their SymPy expressions: the model
kernels' printer (:class:`~varint.models.symbolic.KernelPrinter`) with one
rule more, half-integer powers as products and a square root.

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
integer powers stay ``b**k``, which numba already writes as
multiplications (and a division for k < 0), so a model without
half-integer powers gets the same source, hence the same bits.

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

from ..models.symbolic import KernelPrinter

__all__ = ["StepperPrinter"]


class StepperPrinter(KernelPrinter):
    """:class:`~varint.models.symbolic.KernelPrinter` with b^(p/2), p odd,
    |p| ≥ 3, written as ``((b) * … * math.sqrt(b))`` and its reciprocal for
    p < 0 instead of ``b**(p/2)`` (module docstring).

    >>> import sympy as sp
    >>> x = sp.Symbol("x")
    >>> StepperPrinter().doprint(3 * x**sp.Rational(-5, 2))
    '3/((x) * (x) * math.sqrt(x))'
    """

    def _print_Pow(self, expr, rational=False):
        e = expr.exp
        if not (e.is_Rational and e.q == 2 and abs(e.p) >= 3):
            return super()._print_Pow(expr, rational=rational)
        base = f"({self._print(expr.base)})"
        product = " * ".join([base] * ((abs(e.p) - 1) // 2) + [f"math.sqrt{base}"])
        return f"({product})" if e.p > 0 else f"(1.0 / ({product}))"
