"""Exact zero tests of SymPy expressions, cheaper than ``sympy.simplify``.

:func:`varint.models.from_hamiltonian` recognises the structure of H by
asking whether expressions are identically zero (the mixed derivatives
∂²H/∂q_i∂p_j of a separable H, the off-diagonal terms of a kinetic
energy). ``sympy.simplify`` answers, but its first call imports
``sympy.physics.units`` and tries a dozen rewritings: ~0.1 CPU s on a quiet
machine, most of the making of a model in a fresh process (issue 28). The
answers here are exact, in increasing cost:

1. ``expand``: a polynomial (in any sub-expressions) is zero exactly when
   its expansion is; derivatives of identities such as sin²q + cos²q
   mostly cancel term by term here.
2. A rational function of the symbols is zero exactly when its numerator
   over a common denominator is (``cancel``: polynomial gcds), and is
   otherwise nonzero.
3. Any other expression that evaluates to a nonzero number at a point
   (``evalf``, which raises its working precision until the digits it
   returns are right, Johansson's mpmath) is not identically zero.
4. What is zero at the points and not yet proved zero, i.e. an identity of
   transcendental functions (sin²q + cos²q − 1), is tried with ``trigsimp``
   and, as the last resort, ``simplify``.

So ``simplify`` is reached only for an expression that is zero at every
probe point and is not a rational function, and its answer is then the one
the earlier code gave for every expression.
"""

from __future__ import annotations

import sympy as sp

__all__ = ["is_zero", "without"]

#: Probe values: rationals away from the points where the usual functions
#: are singular or vanish (0, ±1, multiples of π/2), different per symbol
#: so that symmetric cancellations (x − y at x = y) are not taken for zero.
_PROBES = ((sp.Rational(3, 7), sp.Rational(5, 11), sp.Rational(7, 13), sp.Rational(2, 17)),
           (sp.Rational(11, 19), sp.Rational(-4, 23), sp.Rational(13, 29), sp.Rational(-9, 31)))

#: Significant digits asked of ``evalf`` at a probe point, and the size
#: above which its value is taken as nonzero (far above its error).
_DIGITS, _TINY = 30, sp.Float("1e-20")


def _nonzero_at_a_probe(e):
    """True if ``e`` is provably nonzero at one of the probe points (its
    symbols, sorted by name, given the probe values in turn)."""
    symbols = sorted(e.free_symbols, key=lambda s: s.name)
    for probe in _PROBES:
        point = {s: probe[i % len(probe)] + i // len(probe) for i, s in enumerate(symbols)}
        try:
            value = e.evalf(_DIGITS, subs=point)
        except (TypeError, ValueError, ArithmeticError):
            continue
        if not value.is_number or value.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
            continue
        re, im = value.as_real_imag()
        if (re.is_Number and abs(re) > _TINY) or (im.is_Number and abs(im) > _TINY):
            return True
    return False


def is_zero(e) -> bool:
    """Whether the SymPy expression ``e`` is identically zero, proved as
    described in the module docstring."""
    if e == 0:
        return True
    e = sp.expand(e)
    if e == 0:
        return True
    if e.is_rational_function():
        return sp.cancel(e) == 0
    if _nonzero_at_a_probe(e):
        return False
    for rewrite in (sp.cancel, sp.trigsimp):
        if rewrite(e) == 0:
            return True
    return sp.simplify(e) == 0


def without(e, symbols):
    """``e`` rewritten free of ``symbols``, which it depends on only in
    appearance (its derivatives in them are zero), or None if the
    rewritings (``expand``, ``cancel``, ``trigsimp``, then ``simplify``)
    leave one of them in it."""
    symbols = set(symbols)
    for rewrite in (sp.expand, sp.cancel, sp.trigsimp, sp.simplify):
        e = rewrite(e)
        if not e.free_symbols & symbols:
            return e
    return None
