"""The round-off floor experiment: its loop is varint's TM map, and in quick
mode the injected floors scale as δ¹ (GALI₃) and δ² (GALI₄)."""

import numpy as np
import pytest

import varint
from studies import roundoff_floor as rf


def test_the_loop_is_varints_tangent_map():
    # Same scheme, orbit and vectors: the GALIs agree to rounding after
    # 2000 steps (the orders of the floating-point operations differ).
    model, x0 = varint.paper_orbit("R1")
    W0 = np.linalg.qr(np.random.default_rng(3).standard_normal((4, 4)))[0]
    marks = np.array([400, 2000])
    W = rf.gali_loop(np.asarray(x0, dtype=float), W0, *rf.stage_table(0.05), 2000, marks,
                     0.0, rf.INJECT_EVERY, 0)
    ref = varint.gali(model, x0, 100.0, tau=0.05, k=(2, 3, 4), deviations=W0,
                      t_out=marks * 0.05, progress=False)
    for k in (2, 3, 4):
        ours = np.prod(np.linalg.svd(W[:, :, :k], compute_uv=False), axis=-1)
        assert ours == pytest.approx(ref.gali[k], rel=1e-8), k


def test_injection_of_size_zero_changes_nothing():
    _, x0 = varint.paper_orbit("R1")
    W0 = np.eye(4)
    args = (np.asarray(x0, dtype=float), W0, *rf.stage_table(0.05), 3000, np.array([3000]))
    same = rf.gali_loop(*args, 0.0, 1000, 7)
    assert np.array_equal(same, rf.gali_loop(*args, 0.0, 1000, 8))
    assert not np.array_equal(same, rf.gali_loop(*args, 1e-12, 1000, 7))


def test_quick_floors_scale_with_the_injection(figures_quick, paper_quick_dir):
    # Fig. 4 (the figures fixture) has stored the quick arms already.
    res = rf.main(["--quick", "--out", str(paper_quick_dir)])
    ev = res["evidence"]
    assert ev["scaling"][3].holds and ev["scaling"][3].value == pytest.approx(1, abs=0.3)
    assert ev["scaling"][4].holds and ev["scaling"][4].value == pytest.approx(2, abs=0.3)
    # The native floor needs t ≳ 1e7: quick mode cannot compare with it.
    assert ev["small"] is None and rf.holds(ev) is None
    (claim,) = res["claims"]
    assert claim["holds"] and claim["source"] == "own" and len(claim["rules"]) == 2
    assert (paper_quick_dir / "roundoff_floor.png").exists()
    assert (paper_quick_dir / "roundoff_floor.claims.json").exists()
