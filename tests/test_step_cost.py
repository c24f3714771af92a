"""The cost model of a generated step (varint.step_cost): operations counted
from source as written by hand, the branches a step takes, and laws of
the emitted steppers (the LH's rotating-frame drift takes one sine and one
cosine, its kick on a logarithmic potential one logarithm; the lanes of
the constant step evaluate no potential). Nothing here compiles."""

from collections import Counter

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
