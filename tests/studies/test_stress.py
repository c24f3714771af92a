"""The stress study's quick mode, and the claims that hold at its horizon."""

import numpy as np
import pytest

from studies import stress
from studies.common import Claims

#: The schemes of the quick run's stability limits (``stress.main``).
QUICK_SCHEMES = ["SBAB1", "SBAB2C", "ABA864", "SRKN14a"]

#: Energies of the escape part, as the study runs them.
ENERGIES = [0.125, 0.15, 0.16, 0.165, 1 / 6 - 1e-3, 1 / 6 + 5e-3, 0.2]


def check_stability(stab):
    # Higher-order schemes with more force evaluations tolerate larger steps.
    assert stab["SBAB1"] < stab["SBAB2C"] < stab["ABA864"] < stab["SRKN14a"]
    assert 0.5 < stab["SBAB1"] < 2.0  # leapfrog: linear limit ωτ < 2, ω ≈ 1


def check_escape(rows):
    esc = {round(r["energy"], 6): r for r in rows}
    assert esc[0.2]["escaped_at"] is not None and "escaped" in esc[0.2]["message"]
    assert all(np.isfinite(r["X1"]) for r in rows if r["escaped_at"] is None)


def check_overflow(ovf):
    assert ovf["detected"] and 1e4 < ovf["t"] < 2e4
    assert ovf["partial_result_kept"]


def test_stress_laws_at_the_quick_horizons(tmp_path):
    """The laws of the quick run (:func:`test_stress_quick`) from the
    study's own functions at its quick horizons and sizes: stability limits,
    escape, overflow and the long run's bounded energy error. The FPU
    chains' cost per step, which the quick run times (and no law bounds),
    and the figures are left to it."""
    stab = stress.stability_limits(QUICK_SCHEMES, 200.0, 8)
    check_stability({r["scheme"]: r["tau_max"] for r in stab})
    check_escape(stress.escape_energies(ENERGIES, 1e3))
    check_overflow(stress.overflow_without_renormalisation(2e4))
    lr = stress.long_run(1e5)
    claims = Claims("stress", tmp_path)
    stress.long_run_claim(claims, lr.t, lr.energy_error, lr.provenance.counts["steps"], 0.0)
    assert [c["holds"] for c in claims.items] == [True]


@pytest.mark.slow
def test_stress_quick(tmp_path):
    res = stress.main(["--quick", "--out", str(tmp_path)])
    check_stability({r["scheme"]: r["tau_max"] for r in res["stability"]})
    check_escape(res["escape"])
    check_overflow(res["overflow"])
    assert all(c["holds"] is not False for c in res["claims"])
    assert (tmp_path / "stress.claims.json").exists()
    assert (tmp_path / "stress_long_run.png").exists()
