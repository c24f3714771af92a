"""The Taylor method's own conversions: exact solutions in extended
precision, constants rounded in the integrator's precision, integer powers
at zero, and the functions it refuses."""

import mpmath
import numpy as np
import pytest
import sympy as sp

import varint
from varint.baselines.taylor import heyoka_system
from varint.models import from_potential

q = sp.Symbol("q")


def test_extended_precision_solves_an_oscillator_to_the_last_bit_of_double():
    """V = q²/6: ω = 1/√3, an irrational frequency from the constant 1/3.
    After 1000 time units (170 periods) the extended-precision orbit and
    tangent map, rounded to double, are within 3e-16 of the exact solution.
    With 1/3 rounded to double in the equations the phase alone would be off
    by ~1.6e-14; the double-precision integration is off by about 1e-14."""
    model = from_potential(q**2 / 6, [q])
    t = 1000.0
    with mpmath.workdps(40):
        w = 1 / mpmath.sqrt(3)
        c, s = mpmath.cos(w * t), mpmath.sin(w * t)
        x_exact = np.array([float(c), float(-w * s)])
        phi = np.array([[float(c), float(s / w)], [float(-w * s), float(c)]])
    ext = varint.integrate(model, [1.0, 0.0], t, tau=1.0, method="taylor", precision="extended",
                           deviations=np.eye(2))
    assert np.abs(ext.state - x_exact).max() < 3e-16
    assert np.abs(ext.deviations - phi).max() < 3e-16 * np.abs(phi).max()
    dbl = varint.integrate(model, [1.0, 0.0], t, tau=1.0, method="taylor", deviations=np.eye(2))
    assert np.abs(dbl.state - x_exact).max() > 3e-16  # so the bound above discriminates


def test_constants_are_rounded_in_the_integrators_precision():
    x, y = sp.symbols("x y")
    sym = from_potential(x**2 / 3 + sp.pi * y**2, [x, y], inverse_mass=[1, sp.sqrt(2)]).symbolic()
    for fp, digits in ((np.float64, 16), (np.longdouble, 19)):
        text = " ".join(str(rhs) for _, rhs in heyoka_system(sym, fp)[0])
        assert "1.41421356237309504" in text if digits == 19 else "1.4142135623730951" in text
        assert ("0.3333333333333333333" in text) == (digits == 19)


def test_integer_powers_at_zero_do_not_break_the_taylor_recursion():
    """heyoka's Taylor recursion for x**n divides by x; the paper's orbits
    start at x = 0. A quartic oscillator started at q = 0 integrates, and
    agrees with the TM method at high order."""
    model = from_potential(q**2 / 2 + q**4 / 4 + q**3 / 5, [q])
    ref = varint.integrate(model, [0.0, 0.8], 10.0, method="taylor", precision="extended",
                           deviations=np.eye(2))
    tm = varint.integrate(model, [0.0, 0.8], 10.0, tau=0.005, scheme="SRKN14a",
                          deviations=np.eye(2))
    assert np.abs(ref.state - tm.state).max() < 1e-11
    assert np.abs(ref.deviations - tm.deviations).max() < 1e-10


def test_functions_heyoka_lacks_are_refused_by_name():
    model = from_potential(q**2 + sp.sec(q), [q])
    with pytest.raises(ValueError, match="cannot integrate sec"):
        varint.integrate(model, [0.1, 0.0], 1.0, method="taylor")


@pytest.mark.parametrize("orbit, k", [("R2", 2), ("R3", 16)])
def test_taylor_reference_on_the_other_paper_systems(orbit, k):
    """The 3-dof system (masses √2, √3, from the symbolic model) and the FPU
    chain: the reference agrees with the TM method (hand-written kernels,
    masses in double) at small τ; measured 6e-12 and 2e-12 on the orbit.
    Two tangent vectors are compared; the TM run of the chain carries all
    16 (the first two are the same vectors: without renormalisation each
    evolves alone), on the generic stepper of the chain's full spectrum
    that other tests compile, instead of a stepper generated for two."""
    model, x0 = varint.paper_orbit(orbit)
    W0 = np.eye(model.dim)[:, :2]
    ref = varint.integrate(model, x0, 10.0, method="taylor", precision="extended", deviations=W0)
    tm = varint.integrate(model, x0, 10.0, tau=0.01, scheme="ABA864",
                          deviations=np.eye(model.dim)[:, :k])
    assert np.abs(tm.state - ref.state).max() < 1e-10
    assert np.abs(tm.deviations[:, :2] - ref.deviations).max() < 1e-9
