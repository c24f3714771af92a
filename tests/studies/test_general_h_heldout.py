"""studies/general_h_heldout.py and the bar part's AGAMA contender of
studies/hamiltonians.py: the bookkeeping that turns timings into ratios
(made-up rows) and AGAMA's rotating frame (where it installs). The races themselves are the studies'
(minutes)."""

import math

import numpy as np
import pytest

from studies import general_h_heldout as G
from studies import hamiltonians


def test_ratios_at_read_both_fronts_at_each_level():
    """heyoka (1 s, 1e-4), (4 s, 1e-8): at 1e-6 it costs 2 s (log–log); a
    method at (1 s, 1e-6), (2 s, 1e-10) costs 1 s there and √2 s at 1e-8."""
    rows = [{"contender": "heyoka", "seconds": 1.0, "error": 1e-4},
            {"contender": "heyoka", "seconds": 4.0, "error": 1e-8},
            {"contender": "GL8", "seconds": 1.0, "error": 1e-6},
            {"contender": "GL8", "seconds": 2.0, "error": 1e-10},
            {"contender": "DOP853", "seconds": 0.1, "error": 1e-9}]
    out = G.ratios_at(rows)
    assert set(out) == {"GL8"}
    assert out["GL8"][1e-6][0] == pytest.approx(2.0)
    assert out["GL8"][1e-8][0] == pytest.approx(4.0 / math.sqrt(2.0))
    assert out["GL8"][1e-6][1:] == ("at most", "interpolated")
    # A level heyoka's front does not reach has no ratio.
    assert G.ratios_at(rows, levels=(1e-9,))["GL8"][1e-9][0] is None


def test_bar_speedup_takes_the_peers_most_favourable_run():
    rows = [{"contender": "varint a", "seconds": 1.0, "error": 1e-6},
            {"contender": "varint b", "seconds": 2.0, "error": 1e-10},
            {"contender": "AGAMA x", "seconds": 10.0, "error": 1e-5},
            {"contender": "AGAMA y", "seconds": 4.0, "error": 1e-9},
            {"contender": "AGAMA z", "seconds": 1.0, "error": math.nan},
            {"contender": "AGAMA n", "seconds": 1.0, "error": "nan"}]
    ratio, ours, theirs = hamiltonians.bar_speedup(rows, "AGAMA")
    assert ratio == 2.0 and ours["contender"] == "varint b" and theirs["contender"] == "AGAMA y"
    ratio, ours, theirs = hamiltonians.bar_speedup(rows + [
        {"contender": "AGAMA w", "seconds": 1.0, "error": 1e-12}], "AGAMA")
    assert ratio is None and theirs["contender"] == "AGAMA w"
    assert hamiltonians.bar_speedup(rows, "galpy") == (None, None, None)


def test_agama_rotating_frame_takes_varints_state():
    """AGAMA's orbit in its frame rotating with Omega, started from varint's
    (q, p), keeps varint's Jacobi energy H(q, p) to its accuracy (its
    potential is the bar model's); read as (q, ẋ) it would not."""
    pytest.importorskip("agama")
    from varint.models.bar import SPA02, bar_orbit

    model, x0 = bar_orbit("chaotic")
    potential = hamiltonians._agama_bar()
    for q in ([1.0, 0.5, 0.2], [5.0, 1.4, 0.3], [0.3, 4.0, -2.0]):
        assert potential.potential(q) == pytest.approx(model.potential(np.array(q)), rel=1e-12)
    _, traj = hamiltonians._agama_orbit(potential, x0, 20.0, trajsize=21, accuracy=1e-12)
    drift = max(abs(model.energy(x) - model.energy(x0)) for x in traj)
    assert drift < 1e-9 * abs(model.energy(x0))
    # Read as (q, ẋ), the Jacobi energy ½|ẋ|² + Φ − ½Ω²(x² + y²) drifts.
    omega = SPA02["omega"]

    def as_velocity(x):
        return (x[3:] @ x[3:] / 2 + model.potential(x[:3])
                - omega ** 2 * (x[0] ** 2 + x[1] ** 2) / 2)

    assert max(abs(as_velocity(x) - as_velocity(x0)) for x in traj) > 1e-4
