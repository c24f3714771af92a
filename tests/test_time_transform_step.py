"""The automatic fictitious step of the logarithmic Hamiltonian
(varint.time_transform_step) and the map defaults that choose it: the h
chosen on some orbits keeps held-out orbits of the same model within the
tolerance while twice that h does not; a Hénon–Heiles map never switches;
a map of a softened point mass, which no constant step keeps within the
tolerance, does (priced by tests/test_step_agreement.py's rule), says so,
and ``time_transform=None`` keeps constant steps."""

import logging

import numpy as np
import pytest
import sympy as sp

import varint
from varint.accuracy import Reference
from varint.maps import MAP_QUANTILE
from varint.models import from_potential
from varint.models.cr3bp import CR3BP, SUN_JUPITER_MU
from varint.time_transform import LogHamiltonian
from varint.time_transform_step import choose_h

TOL = 1e-6


def _plummer_orbits(seed, m):
    """Eccentric bound orbits of a softened point mass (ε = 1e-3), with
    pericentres down to ~0.01."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.5, 1.0, m), np.zeros(m), np.zeros(m),
                            rng.uniform(0.05, 0.5, m)])


def _cr3bp_orbits(seed, m):
    """Sun–Jupiter orbits on the section y = 0 at C = 3.05 (studies/map_steps.py)."""
    model = CR3BP(SUN_JUPITER_MU)
    rng = np.random.default_rng(seed)
    grid = model.section_grid(3.05, np.sort(rng.uniform(0.3, 0.85, m)),
                              np.sort(rng.uniform(-0.3, 0.3, m)))
    return grid.states


def _model(which):
    if which == "plummer":
        x, y = sp.symbols("x y")
        return from_potential(-1 / sp.sqrt(x**2 + y**2 + sp.Float(1e-3)**2), [x, y])
    return CR3BP(SUN_JUPITER_MU)


def _errors(lh, X, t_end, h):
    out = lh.outputs(X, None, t_end, h, every=t_end / 50)
    assert (out.status == 0).all()
    return Reference(lh.model, X).errors(out.x_worst)["energy_error"]


@pytest.mark.parametrize("which", ["plummer", "cr3bp"])
def test_chosen_h_meets_the_tolerance_on_held_out_orbits(which):
    """h from a pilot on one set of orbits: 16 other orbits of the model
    run to the map's t_end (twice the pilot's) meet the tolerance at the
    map's quantile within the ladder's resolution (one rung, 2^(1/4) in h,
    is 2^(p/4) = 2 in the error of an order-4 scheme; measured: Plummer
    1.09e-6, three held-out orbits of 16 just above 1e-6), and at 2h (error
    ×2^p) they miss it."""
    model = _model(which)
    orbits = _plummer_orbits if which == "plummer" else _cr3bp_orbits
    lh = LogHamiltonian(model, "ABA864")
    t_end = 40.0
    h, choice = choose_h(lh, orbits(0, 16), t_end / 2, TOL, quantile=MAP_QUANTILE)
    assert choice["rule"] == "pilot" and choice["h"] == h
    held_out = orbits(1, 16)
    e = _errors(lh, held_out, t_end, h)
    assert np.quantile(e, MAP_QUANTILE) <= 2 * TOL, (h, np.sort(e))
    assert np.quantile(_errors(lh, held_out, t_end, 2 * h), MAP_QUANTILE) > 2 * TOL


def test_henon_heiles_defaults_never_switch():
    """A Hénon–Heiles FLI map with the defaults is the constant-step map,
    bit for bit (``time_transform=None``)."""
    hh = varint.models.HenonHeiles()
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.65, 4), np.linspace(-0.4, 0.4, 3))
    a = varint.chaos_map(hh, grid, "fli", t_end=50.0, progress=False)
    b = varint.chaos_map(hh, grid, "fli", t_end=50.0, progress=False, time_transform=None)
    assert a.provenance.method == "tm" and np.array_equal(a.values, b.values)


def test_near_singular_defaults_take_the_log_hamiltonian(caplog):
    """A softened point mass (ε = 1e-3) with eccentric orbits: no constant
    step meets the map's tolerance (its pilot falls back, and that map's
    energy errors are O(1) and more); the LH's step chosen by indicator
    agreement is priced cheaper than constant steps, so the defaults run
    the LH, say so (method, the prices, one log line) and give the explicit
    LH map at that h bit for bit, accurate; time_transform=None keeps
    constant steps."""
    model = _model("plummer")
    X = _plummer_orbits(2, 8)
    with caplog.at_level(logging.INFO, logger="varint.maps"):
        r = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False)
    assert r.provenance.method == "tm+log"
    choice = r.provenance.tau_choice
    assert choice["rule"] == "indicator" and choice["prices"]["log"] < choice["prices"]["constant"]
    assert sum("logarithmic-Hamiltonian step" in m for m in caplog.messages) == 1
    explicit = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                time_transform="log", tau=choice["h"])
    assert np.array_equal(r.values, explicit.values, equal_nan=True)
    assert r.accuracy.accurate.all()
    with pytest.warns(varint.AccuracyWarning):
        plain = varint.chaos_map(model, X, "fli", t_end=40.0, progress=False,
                                 time_transform=None)
    assert plain.provenance.method == "tm" and not plain.accuracy.accurate.all()
