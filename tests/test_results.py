"""Results carry their provenance and survive a save/load round trip."""

import numpy as np

import varint


def test_provenance_records_what_determines_the_run(c1):
    model, x0 = c1
    r = varint.lyapunov_spectrum(model, x0, 20.0, tau=0.1, scheme="ABA864", seed=11,
                                 n_exponents=2)
    p = r.provenance
    assert p.kind == "lyapunov" and p.method == "tm"
    assert p.model["name"] == "HenonHeiles" and np.allclose(p.x0, x0)
    assert p.method_options["scheme"]["name"] == "ABA864"
    assert (p.tau, p.t_end, p.seed) == (0.1, 20.0, 11)
    assert {"python", "varint", "numpy", "scipy", "numba"} <= set(p.versions)
    assert p.counts["steps"] == 200 and p.counts["gradient"] >= 200 * 7
    assert p.wall_time > 0


def test_save_and_load_round_trip(tmp_path, r1):
    g = varint.gali(*r1, 30.0, k=(2, 4))
    g.save(tmp_path / "g.npz")
    h = varint.load_result(tmp_path / "g.npz")
    assert type(h) is varint.GALIResult
    assert np.array_equal(h.t, g.t) and set(h.gali) == {2, 4}
    assert np.array_equal(h.gali[4], g.gali[4])
    assert h.provenance == g.provenance
    i = varint.integrate(*r1, 10.0, t_out=5, deviations=np.eye(4)[:, :1])
    i.save(tmp_path / "i.npz")
    j = varint.load_result(tmp_path / "i.npz")
    assert np.array_equal(j.states, i.states) and np.array_equal(j.deviations, i.deviations)


def test_output_times(c1):
    model, x0 = c1
    r = varint.integrate(model, x0, 1.0, tau=0.1, t_out=[0.3, 0.5, 1.0])
    assert np.allclose(r.t, [0.3, 0.5, 1.0]) and r.states.shape == (3, 4)
    # Default for indicators: log-spaced, ~10 per decade, ending at t_end.
    lce = varint.lyapunov_spectrum(model, x0, 100.0, tau=0.1)
    assert lce.t[-1] == 100.0 and 25 <= len(lce.t) <= 35
    assert np.all(np.diff(np.log(lce.t)) > 0)
    # Only the final time for integrate by default.
    assert varint.integrate(model, x0, 1.0, tau=0.1).t.tolist() == [1.0]
