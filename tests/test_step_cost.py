"""The cost model of a generated step (varint.step_cost): operations counted
from source as written by hand, the branches a step takes, and laws of
the emitted steppers (the LH's rotating-frame drift takes one sine and one
cosine, its kick on a logarithmic potential one logarithm; the lanes of
the constant step evaluate no potential). Nothing here compiles."""

import json
import platform
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import varint
from varint import step_cost
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.schemes import DRIFT, get_scheme, stage_arrays
from varint.time_transform import LogHamiltonian

SOURCE = '''
def step(x, V, log, k):
    a = x[0] * 2.0 + x[1] / 3.0
    if log:
        a = math.sqrt(a)
    else:
        a = math.log(a)
    if a - a != 0.0:
        b = a * a * a
        return 1
    for c in range(k):
        V[c, 0] += fma(a, V[c, 1], 1.0) - a ** 2
    y = a if a > 0.0 else -a
    return 0
'''


def test_operations_as_counted_by_hand():
    """Line by line: 2 loads, a mul, a div, an add; sqrt (log's branch);
    the failure test (sub, compare), its body not; per vector (k = 3) a
    load and store of V[c, 0] (augmented: read and written, one Subscript
    node), a load of V[c, 1], the augmented add, one fma, a sub, a**2 as one
    multiplication; the conditional expression's test."""
    counts = step_cost.operations(SOURCE, "step", {"log": True, "k": 3})
    assert counts == Counter({"memory": 2 + 3 * 2, "mul": 1 + 3, "div": 1, "add": 1 + 1 + 3 * 2,
                              "sqrt": 1, "compare": 1 + 1, "fma": 3})
    other = step_cost.operations(SOURCE, "step", {"log": False, "k": 0})
    assert other["log"] == 1 and other["sqrt"] == 0 and other["fma"] == 0


def test_unknown_loop_and_function_are_refused():
    with pytest.raises(ValueError, match="trip count is not known"):
        step_cost.operations(SOURCE, "step", {"log": True})
    with pytest.raises(ValueError, match="no function 'nope'"):
        step_cost.operations(SOURCE, "nope", {})


def test_weighted_sums_the_table():
    counts = Counter({"add": 3, "sqrt": 2})
    table = step_cost.WEIGHTS
    assert step_cost.weighted(counts) == pytest.approx(3 * table["add"] + 2 * table["sqrt"])
    assert set(table) == set(step_cost.KINDS)


def _stages(scheme):
    kinds, _, _ = stage_arrays(get_scheme(scheme), 1.0)
    return int((kinds == DRIFT).sum()), int((kinds != DRIFT).sum())


def test_rotating_frame_drift_takes_a_sine_and_a_cosine():
    """The LH drift of the three-body problem rotates by Ωτ with τ = h/W,
    a new angle every drift: one sine and one cosine each; no logarithm."""
    lh = LogHamiltonian(CR3BP(SUN_JUPITER_MU), "ABA864")
    _, counts = step_cost.log_gradient_cost(lh)
    drifts, _ = _stages("ABA864")
    assert counts["sin"] == counts["cos"] == drifts and counts["log"] == 0


def test_logarithmic_kick_takes_a_logarithm():
    """The LH kick of V = ½ ln(R² + x² + y²/q²) evaluates V (for U = C −
    V): one logarithm per kick, none in the drifts."""
    x, y = sp.symbols("x y")
    model = from_potential(sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2,
                           [x, y])
    lh = LogHamiltonian(model, "ABA864")
    _, counts = step_cost.log_gradient_cost(lh)
    _, kicks = _stages("ABA864")
    assert counts["log"] == kicks and counts["sin"] == counts["cos"] == 0
    # The constant step's lanes need ∇V and D²V only (rational here): the
    # logarithms they take are the FLI accumulator's, one per step at most.
    acc = varint.INDICATORS["fli"].accumulator_for({})
    _, lanes = step_cost.constant_gradient_cost(model, "SRKN14a", 1, acc)
    assert lanes["log"] <= 1 and lanes["sin"] == lanes["cos"] == 0


def test_costs_are_positive_and_reproducible():
    """The same model and scheme price the same, bit for bit (no timing)."""
    model = CR3BP(SUN_JUPITER_MU)
    acc = varint.INDICATORS["fli"].accumulator_for({})
    a = step_cost.constant_gradient_cost(model, "SRKN14a", 1, acc)[0]
    b = step_cost.constant_gradient_cost(CR3BP(SUN_JUPITER_MU), "SRKN14a", 1, acc)[0]
    c = step_cost.log_gradient_cost(LogHamiltonian(model, "ABA864"))[0]
    d = step_cost.log_gradient_cost(LogHamiltonian(CR3BP(SUN_JUPITER_MU), "ABA864"))[0]
    assert a == b > 0 and c == d > 0


def test_lh_over_lanes_is_priced_below_one_orbit_at_a_time():
    """The LH's lanes table (fitted on the same models' maps over lanes)
    prices arithmetic and divisions no higher than the one-orbit table
    (they overlap across the lanes; a library call costs about as much,
    3.3 against 3.0 ns as fitted on an AMD EPYC), and the LH's force
    evaluation over lanes below one orbit's on the two race models (the
    lanes run the same statements, several orbits at once)."""
    overlapping = step_cost.CLASSES["arithmetic"] + step_cost.CLASSES["division"]
    assert all(step_cost.LH_LANES_WEIGHTS[k] <= step_cost.LH_WEIGHTS[k] for k in overlapping)
    x, y = sp.symbols("x y")
    cored = from_potential(sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2, [x, y])
    for model in (cored, CR3BP(SUN_JUPITER_MU)):
        lh = LogHamiltonian(model, "ABA864")
        one, counts = step_cost.log_gradient_cost(lh)
        lanes, same = step_cost.log_gradient_cost(lh, lanes=True)
        assert 0 < lanes < one and same == counts


def test_a_negative_power_is_an_inverse_that_keeps_lanes_scalar():
    """x**(-2) is one multiplication and one inverse (numba's, which keeps
    the loop around it from vectorising); 1/(x*x) a multiplication and a
    division, which vectorises; library calls keep it scalar, a square
    root does not."""
    src = ("def f(x):\n    a = x[0] ** (-2)\n    b = 1.0 / (x[1] * x[1])\n"
           "    c = math.sqrt(x[2])\n    d = math.exp(x[3])\n")
    counts = step_cost.operations(src, "f", {})
    assert counts["invert"] == 1 and counts["div"] == 1 and counts["mul"] == 2
    assert not step_cost.vectorises(counts)
    assert step_cost.vectorises(Counter({"div": 3, "sqrt": 2, "mul": 5}))
    assert not step_cost.vectorises(Counter({"exp": 1}))
    assert set(step_cost.SCALAR_KINDS) <= set(step_cost.KINDS)
    for table in (step_cost.LH_WEIGHTS, step_cost.VECTOR_LANE_WEIGHTS,
                  step_cost.SCALAR_LANE_WEIGHTS):
        assert set(table) == set(step_cost.KINDS)


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 assembly")
def test_numba_vectorises_a_division_but_not_a_negative_power():
    """The premise of step_cost.vectorises, on the compiler itself: the
    same loop over lanes compiles to packed divisions with 1/(v*v) and to
    none with v**(-2)."""
    from numba import njit

    def power(x, out):
        for b in range(x.shape[0]):
            out[b] = x[b] ** (-2) + out[b]

    def division(x, out):
        for b in range(x.shape[0]):
            out[b] = 1.0 / (x[b] * x[b]) + out[b]

    x, out = np.linspace(1.0, 2.0, 64), np.zeros(64)
    asm = {}
    for f in (power, division):
        g = njit(error_model="numpy")(f)
        g(x, out)
        asm[f.__name__] = g.inspect_asm(g.signatures[0])
    assert "divpd" in asm["division"]
    assert "divpd" not in asm["power"]


def test_emitted_lanes_vectorise_where_the_measurements_say():
    """The cored potential's Hessian takes (R² + x² + y²/q²)^(−2), printed
    as a division (varint.codegen.printer; as numba's ``**(-2)`` its lanes
    ran scalar, 32 ns per force evaluation against 10 for Hénon–Heiles,
    studies/results/switch_check_quick.json); the three-body problem's
    half-integer powers are printed as products and square roots: all
    vectorise. A library call in the step (Toda's exponentials) does not."""
    acc = varint.INDICATORS["fli"].accumulator_for({})
    x, y = sp.symbols("x y")
    cored = from_potential(sp.log(sp.Float(0.03)**2 + x**2 + y**2 / sp.Float(0.8)**2) / 2,
                           [x, y])
    flags = {name: step_cost.vectorises(
        step_cost.constant_gradient_cost(m, "SRKN14a", 1, acc)[1])
        for name, m in (("cored", cored), ("cr3bp", CR3BP(SUN_JUPITER_MU)),
                        ("hh", varint.models.HenonHeiles()),
                        ("toda", from_potential(sp.exp(x) + sp.exp(-y) + sp.exp(y - x), [x, y])))}
    assert flags == {"cored": True, "cr3bp": True, "hh": True, "toda": False}


def test_held_out_ratios_are_predicted():
    """The LH/constant cost per force evaluation the tables predict now,
    from the emitted source, against the ratio measured on each held-out
    model of studies/switch_check.py (stored; models it was not fitted
    on): within its tolerance, and on the same side of 1."""
    from studies import switch_check

    stored = json.loads((Path(switch_check.__file__).parent / "results"
                         / "switch_check.json").read_text())
    rows = stored["heldout"]["rows"]
    assert rows
    acc = varint.INDICATORS["fli"].accumulator_for({})
    models = {name: model for name, model, _ in switch_check.heldout(1)}
    for row in rows:
        model = models[row["model"]]
        lh = step_cost.log_gradient_cost(LogHamiltonian(model, "ABA864"))[0]
        lanes = step_cost.constant_gradient_cost(model, "SRKN14a", 1, acc)[0]
        predicted, measured = lh / lanes, row["measured"]["ratio"]
        assert max(predicted / measured, measured / predicted) <= switch_check.TOLERANCE, row
        assert (predicted > 1) == (measured > 1), row
