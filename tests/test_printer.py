"""Half-integer powers in the generated steppers (varint.codegen.printer):
none is printed as ``**``; the products and square root are within a few
units in the last place of the exact power (mpmath at 60 digits, an
independent reference), non-finite exactly where numba's ``pow`` is, and a
model without such powers is printed as before (same source, same bits).
Negative integer powers: printed as one over the positive power, the bits
of numba's own ``b**(-k)``, and a loop over lanes around them vectorises
(LLVM's IR) where numba's did not."""

import math
import platform
import re

import mpmath
import numpy as np
import pytest
import sympy as sp
from numba import njit

from varint.codegen.expressions import ensure_form, expressions, model_key
from varint.codegen.lh import Flow, lh_source
from varint.codegen.printer import StepperPrinter
from varint.codegen.stepper import Plan, generated_source
from varint.kernels.checks import HUGE_Q2
from varint import paper_orbit
from varint.models import CR3BP, HenonHeiles, ThreeDof
from varint.models.symbolic import KernelPrinter
from varint.schemes import DRIFT, get_scheme, stage_arrays

#: ``**`` with a half-integer exponent, as SymPy prints it (3/2, (-5/2)) or
#: as a float (1.5).
HALF_POWER = re.compile(r"\*\*\s*\(?\s*-?\d*[13579]/2\b|\*\*\s*\(?\s*-?\d*\.5\b")

b = sp.Symbol("b")
EXPONENTS = (3, -3, 5, -5, 7, -7)


def _plan(scheme, k):
    kinds, _, hc = stage_arrays(get_scheme(scheme), 1.0)
    corrected = (hc != 0.0) & (kinds != DRIFT)
    return Plan(kinds=tuple(int(v) for v in kinds), corrected=tuple(bool(c) for c in corrected),
                k=k, accumulator="")


def _expressions(model):
    key = model_key(model)
    ensure_form(model, key)
    return expressions(key)


def _compiled(printer, expr):
    """``expr`` (in b) printed by ``printer``, compiled as the steppers are."""
    scope = {"math": math}
    exec(f"def f(b):\n    return {printer.doprint(expr)}\n", scope)
    return njit(error_model="numpy")(scope["f"])


def test_the_printed_steppers_have_no_half_integer_power():
    """The constant step's source (one orbit and lanes, a corrector and a
    rotating frame: the three-body problem with SBAB2C) and the LH's hold
    no ``**`` with a half-integer exponent; before, the constant step held
    several per kick."""
    model = CR3BP(0.000954)
    source = generated_source(_expressions(model), _plan("SBAB2C", 1))
    assert "math.sqrt(" in source
    assert not HALF_POWER.search(source), HALF_POWER.search(source)
    x, y, px, py = sp.symbols("x y p_x p_y")
    V = -1 / sp.sqrt(1 + x**2 + y**2 / sp.Rational(16, 25))
    lh = lh_source((px**2 + py**2) / 2, V, (x, y), (px, py), Flow("free", (1.0, 1.0)), (0, 1, 0))
    assert "math.sqrt(" in lh and not HALF_POWER.search(lh), HALF_POWER.search(lh)
    # The old printer wrote them as powers: what the test would catch.
    assert HALF_POWER.search(KernelPrinter().doprint(V.diff(x).diff(y)))


@pytest.mark.parametrize("model", [HenonHeiles(), ThreeDof(), paper_orbit("R3")[0]],
                         ids=["HH", "ThreeDof", "FPU"])
def test_a_model_without_half_integer_powers_prints_as_before(model):
    """Polynomial potentials (and ThreeDof's √2, √3 constants) are printed
    character for character as by the model kernels' printer: their
    generated steppers are unchanged, bit for bit (the stored fingerprints'
    generated-stepper models)."""
    E = _expressions(model)
    old, new = KernelPrinter(), StepperPrinter()
    exprs = [*E.g, *E.H.values(), *E.gc, *E.HC.values()]
    assert exprs
    for e in exprs:
        assert new.doprint(e) == old.doprint(e)


def _grid():
    """Bases from 1e-320 (subnormal) to 1e308, 20 per decade with
    irregular mantissas, and the powers of two at the range's edges."""
    rng = np.random.default_rng(7)
    exps = np.linspace(-320.0, 308.0, 20 * 628)
    values = 10.0 ** (exps + rng.uniform(-0.025, 0.025, exps.size))
    edges = [2.0 ** e for e in range(-1074, 1024, 7)]
    return np.unique(np.concatenate([values[np.isfinite(values) & (values > 0)], edges]))


@pytest.mark.parametrize("p", EXPONENTS)
def test_products_are_within_a_few_ulp_of_the_exact_power(p):
    """Against b^(p/2) at 60 digits: within (|p| + 3)/2 + 1 units in the
    last place of the exact value wherever it is a normal double (one
    rounded square root, (|p| − 1)/2 rounded products, a rounded division,
    and for p < 0 near the largest double a subnormal denominator); where
    the exact value is below the normal range, within 2.3e-308; where it
    overflows, inf; and finite exactly where numba's ``pow`` is."""
    new = _compiled(StepperPrinter(), b ** sp.Rational(p, 2))
    old = _compiled(KernelPrinter(), b ** sp.Rational(p, 2))
    assert "sqrt" in StepperPrinter().doprint(b ** sp.Rational(p, 2))
    tiny, biggest = np.finfo(float).tiny, np.finfo(float).max
    bound = (abs(p) + 3) / 2 + 1
    mpmath.mp.dps = 60
    worst = 0.0
    for value in _grid():
        got = new(value)
        exact = mpmath.power(mpmath.mpf(float(value)), mpmath.mpf(p) / 2)
        assert math.isfinite(got) == math.isfinite(old(value)), (value, got, old(value))
        if exact > biggest:
            assert got == math.inf, (value, got)
        elif exact >= tiny:
            ulp = math.ulp(float(exact))
            error = float(abs(mpmath.mpf(got) - exact)) / ulp
            worst = max(worst, error)
            assert error <= bound, (value, got, float(exact), error)
        else:
            assert abs(got - float(exact)) <= 2.3e-308, (value, got, float(exact))
    assert worst > 0.0      # the grid reached values where the two differ


@pytest.mark.parametrize("p", EXPONENTS)
def test_edge_values_are_pows(p):
    """NaN for finite b < 0 and b = NaN; at +0 and +inf the value of
    ``pow`` (0 or inf); at −0, which no sum of squares gives, a zero or an
    infinity as ``pow``'s, possibly of the other sign; at −inf NaN, where
    ``pow`` gives inf or 0 (the printer's docstring: only a base that
    overflowed past the negative bases, already NaN, gets there)."""
    new = _compiled(StepperPrinter(), b ** sp.Rational(p, 2))
    old = _compiled(KernelPrinter(), b ** sp.Rational(p, 2))
    for value in (-1e-300, -1.0, -1e300, math.nan):
        assert math.isnan(new(value)) and math.isnan(old(value))
    assert math.isnan(new(-math.inf)) and old(-math.inf) == math.pow(-math.inf, p / 2)
    with np.errstate(divide="ignore"):
        zero = float(np.power(0.0, p / 2))      # C's pow: 0 or inf (math.pow raises)
    for value, expected in ((0.0, zero), (math.inf, 0.0 if p < 0 else math.inf)):
        assert new(value) == old(value) == expected
        assert math.copysign(1.0, new(value)) == math.copysign(1.0, old(value))
    assert abs(new(-0.0)) == abs(old(-0.0)) == zero


def test_the_derivatives_are_non_finite_where_they_were():
    """The three-body problem's ∇V and D²V as a kick evaluates them (CSE,
    then printed), old printer against new: at the primaries (division by
    zero), at distances whose square is subnormal or zero, and at
    coordinates so large that r² or r⁵ overflows, each derivative is
    non-finite exactly where it was (so the stepper's finiteness checks
    stop the same orbits), and the finite ones agree to round-off where the
    stepper runs an orbit at all (|q|² below ``HUGE_Q2``: beyond, r⁻⁵ is 0
    instead of a subnormal number, and the orbit has escaped)."""
    mu = 0.000954
    E = _expressions(CR3BP(mu))
    exprs = [*E.g, *E.H.values()]
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t_"))

    def compiled(printer):
        lines = [f"    {s} = {printer.doprint(e)}" for s, e in temps]
        lines.append(f"    return ({', '.join(printer.doprint(e) for e in reduced)},)")
        scope = {"math": math}
        exec("def f(q0, q1):\n" + "\n".join(lines) + "\n", scope)
        return njit(error_model="numpy")(scope["f"])

    old, new = compiled(KernelPrinter()), compiled(StepperPrinter())
    points = [(-mu, 0.0), (1 - mu, 0.0), (-mu + 1e-160, 0.0), (1 - mu, 1e-162),
              (-mu + 1e-200, 1e-200), (0.5, 0.3), (1e100, 0.0), (1e150, 1e150),
              (3e61, 0.0), (1e62, 1e62), (1e154, 0.0), (1e155, 1e155), (-1e200, 1e200),
              (1e-300, 1e-300), (3e49, 1e49)]
    seen = set()
    for q in points:
        a, c = np.array(old(*q)), np.array(new(*q))
        assert np.array_equal(np.isfinite(a), np.isfinite(c)), (q, a, c)
        fin = np.isfinite(a)
        if math.hypot(*q) < math.sqrt(HUGE_Q2):
            np.testing.assert_allclose(c[fin], a[fin], rtol=1e-13, atol=1e-300)
        seen.add(bool(fin.all()))
    assert seen == {True, False}        # both kinds of point were met


NEGATIVE = (2, 3, 4, 5)


@pytest.mark.parametrize("k", NEGATIVE)
def test_a_negative_integer_power_is_numbas_bits(k):
    """``(1.0 / b**k)`` against numba's ``b**(-k)`` over bases of both signs
    from subnormal to the largest double: the same bits wherever numba's
    returns (the same product and the same correctly rounded division),
    and ±inf as C's ``pow`` where b^k underflows to zero and numba's raises
    ZeroDivisionError instead."""
    expr = b ** -k
    printed = StepperPrinter().doprint(expr)
    assert "**(-" not in printed and printed == f"(1.0 / b**{k})"
    new = _compiled(StepperPrinter(), expr)
    old = _compiled(KernelPrinter(), expr)
    grid = _grid()
    raised = 0
    for value in np.concatenate([grid, -grid[::7]]):
        got = new(value)
        try:
            want = old(value)
        except ZeroDivisionError:
            raised += 1
            with np.errstate(divide="ignore", over="ignore"):
                assert got == float(np.power(value, -k)) and math.isinf(got), (value, got)
            continue
        assert np.float64(got).view(np.int64) == np.float64(want).view(np.int64), (value, got, want)
    assert raised      # the grid reached the underflow, where the two differ


def _lanes_ir(printer):
    """LLVM IR of a loop over lanes that adds (1 + x²)^(−2), printed by
    ``printer``, compiled as the lanes are (numpy error model)."""
    x = sp.Symbol("x")
    body = printer.doprint((1 + x**2) ** -2).replace("x", "x[i]")
    scope = {"math": math}
    exec(f"def f(x, out):\n    for i in range(x.shape[0]):\n        out[i] += {body}\n", scope)
    f = njit(error_model="numpy")(scope["f"])
    f(np.linspace(0.0, 1.0, 64), np.zeros(64))
    return f.inspect_llvm(f.signatures[0])


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64", "aarch64", "arm64"),
                    reason="a target with vector doubles")
def test_a_loop_over_lanes_vectorises_the_printed_negative_power():
    """The reason for the rule: with ``b**(-2)`` (the model kernels'
    printer, SymPy's) numba's zero-divisor test keeps the loop scalar, no
    vector division in its IR; with ``(1.0 / b**2)`` LLVM vectorises it."""
    vector_div = re.compile(r"fdiv (?:\w+ )*<\d+ x double>")
    assert vector_div.search(_lanes_ir(StepperPrinter()))
    assert not vector_div.search(_lanes_ir(KernelPrinter()))
