"""The generated stepper (varint.codegen) against the generic one,
its SIMD lanes against its one-orbit loop, and sparse renormalisation
against renormalising every step."""

import numpy as np
import pytest
import sympy

import varint
from varint.cachedir import CacheDirWarning
from varint.codegen import expressions as X
from varint.codegen import stepper as G
from varint.methods.tm import TangentMapPropagator
from varint.models import HenonHeiles, from_potential
from varint.protocol import Renorm, Status
from varint.state import RunState

HH = HenonHeiles()


def _hh_orbits(m, energy=0.125, spread=0.08):
    """m Hénon–Heiles states on the x = 0 section at the given energy."""
    y = np.linspace(-0.2, 0.2 + spread, m)
    py = np.zeros(m)
    v = 0.5 * y**2 - y**3 / 3
    px = np.sqrt(2 * (energy - v))
    return np.column_stack([np.zeros(m), y, px, py])


def _deviations(m, k, seed=3):
    return np.random.default_rng(seed).standard_normal((m, 4, k))


def _advance(model, x0, W0, scheme, renorm, n, generated, **options):
    p = TangentMapPropagator(model, 0.05, renorm, scheme=scheme, parallel=False, **options)
    state = RunState.start(x0.copy(), W0.copy())
    if not generated:
        p._generated[state.k] = None          # force the generic stepper
    else:
        assert p._stepper(state.k) is not None
    p.advance(state, n)
    return state


@pytest.mark.parametrize("scheme, k, renorm", [
    ("SBAB2C", 4, Renorm.QR),     # the paper's configuration: corrector, full spectrum
    ("ABA864", 1, Renorm.NONE),   # raw vectors: no renormalisation to hide differences
    # Corrector on an ABA-type scheme, unit vectors (GALI's renormalisation,
    # column by column: one vector checks it, and the generic stepper is
    # then the one compiled for ABA864 above: 8-10 CPU s cold less).
    ("SABA2C", 1, Renorm.NORMALIZE),
])
def test_generated_equals_generic_to_round_off(scheme, k, renorm):
    """Straight-line derivatives with CSE and the generic banded kernels are
    the same map: after 400 steps of a chaotic orbit, relative differences
    stay at round-off amplified by the orbit's own divergence (< 1e-10)."""
    x0 = _hh_orbits(3)
    W0 = _deviations(3, k)
    a = _advance(HH, x0, W0, scheme, renorm, 400, generated=True, renormalize_every=1)
    b = _advance(HH, x0, W0, scheme, renorm, 400, generated=False)
    assert (a.status == Status.OK).all() and (b.status == Status.OK).all()
    assert np.abs(a.x - b.x).max() < 1e-10 * np.abs(b.x).max()
    la = np.log(np.abs(a.acc_m)) + a.acc_e * np.log(2)
    lb = np.log(np.abs(b.acc_m)) + b.acc_e * np.log(2)
    assert np.abs(la - lb).max() < 1e-9
    scale = np.abs(b.W).max()
    assert np.abs(a.W - b.W).max() < 1e-9 * scale


def test_generated_from_potential_with_masses():
    """A from_potential model with unequal masses and a coupling: generated
    equals generic (the corrector C = ∇Vᵀ M⁻¹ ∇V carries the masses). (One
    vector: the masses act on the orbit and on each vector alike, and a
    generated stepper's straight-line code grows with the vectors.)"""
    import sympy as sp

    q = sp.symbols("q0:3")
    V = sum(qi**2 / 2 for qi in q) + q[0] * q[1] ** 2 + q[1] ** 2 * q[2] ** 2 / 4
    model = from_potential(V, q, inverse_mass=[1.0, 0.5, 2.0])
    rng = np.random.default_rng(1)
    x0 = 0.2 * rng.standard_normal((2, 6))
    W0 = rng.standard_normal((2, 6, 1))
    a = _advance(model, x0, W0, "SBAB2C", Renorm.QR, 300, generated=True, renormalize_every=1)
    b = _advance(model, x0, W0, "SBAB2C", Renorm.QR, 300, generated=False)
    assert np.abs(a.x - b.x).max() < 1e-11
    assert np.abs(a.W - b.W).max() < 1e-9


def test_lanes_are_bitwise_the_one_orbit_stepper():
    """70 orbits (one full block of 64 lanes and a padded one), one of which
    escapes: the batch gives bitwise what each orbit gives alone, including
    the escaping orbit's status, failure step and frozen state."""
    m = 70
    x0 = _hh_orbits(m)
    x0[5] = [0.0, 0.0, 1.0, 0.0]           # E = 0.5 > 1/6: leaves the well
    W0 = _deviations(m, 2)
    model = HenonHeiles(escape_radius=5.0)
    outputs = np.array([100, 600])
    p = TangentMapPropagator(model, 0.05, Renorm.QR, parallel=False)
    batch = RunState.start(x0.copy(), W0.copy())
    snaps = p.advance(batch, 600, outputs)
    assert batch.status[5] != Status.OK and (np.delete(batch.status, 5) == Status.OK).all()
    for i in (0, 5, 63, 64, 69):
        q = TangentMapPropagator(model, 0.05, Renorm.QR, parallel=False)
        one = RunState.start(x0[i:i + 1].copy(), W0[i:i + 1].copy())
        s1 = q.advance(one, 600, outputs)
        assert one.status[0] == batch.status[i]
        assert one.fail_step[0] == batch.fail_step[i]
        np.testing.assert_array_equal(one.x[0], batch.x[i])
        np.testing.assert_array_equal(one.W[0], batch.W[i])
        np.testing.assert_array_equal(one.acc_m[0], batch.acc_m[i])
        np.testing.assert_array_equal(one.acc_e[0], batch.acc_e[i])
        if i != 5:
            np.testing.assert_array_equal(s1.x[:, 0], snaps.x[:, i])
            np.testing.assert_array_equal(s1.W[:, 0], snaps.W[:, i])


def test_parallel_blocks_of_lanes_are_bitwise_the_serial_ones():
    """130 orbits (three blocks of 64 lanes, the last padded) on the kernel
    over blocks in parallel (numba's chunk size set around the call, so
    that the kernel is cached) and serially: the same bits, status and
    snapshots."""
    m = 130
    x0, W0 = _hh_orbits(m), _deviations(m, 2)
    outputs = np.array([50, 200])
    runs = []
    for parallel in (True, False):
        p = TangentMapPropagator(HenonHeiles(), 0.05, Renorm.QR, parallel=parallel)
        state = RunState.start(x0.copy(), W0.copy())
        runs.append((state, p.advance(state, 200, outputs)))
    (a, sa), (b, sb) = runs
    for field in ("x", "W", "acc_m", "acc_e", "status"):
        assert getattr(a, field).tobytes() == getattr(b, field).tobytes(), field
    assert sa.x.tobytes() == sb.x.tobytes() and sa.W.tobytes() == sb.W.tobytes()


@pytest.mark.parametrize("name", ["fli", "megno"])
def test_inline_accumulators_lanes_orbit_chunks_and_generic(name):
    """The accumulators ``lanes`` writes out inline (FLI, MEGNO): lanes give
    bitwise what the one-orbit stepper gives, in one call or in several
    (chunking), with the outputs' accumulators; and the generic stepper's
    values (FLI as a running sum of logarithms, not the generated peak) to
    round-off."""
    from varint.indicators.megno import FLI_ACCUMULATOR, MEGNO_ACCUMULATOR

    acc = FLI_ACCUMULATOR if name == "fli" else MEGNO_ACCUMULATOR
    m = 20
    x0, W0 = _hh_orbits(m), _deviations(m, 1)
    W0 /= np.linalg.norm(W0, axis=1, keepdims=True)
    outputs = np.array([100, 400])

    def run(rows, splits, generated=True):
        p = TangentMapPropagator(HH, 0.05, Renorm.NORMALIZE, acc, parallel=False)
        state = RunState.start(x0[rows].copy(), W0[rows].copy())
        state.extra[acc.key] = np.tile(np.array(acc.initial), (len(rows), 1, 1))
        if not generated:
            p._generated[1] = None
            p.advance(state, sum(splits))
            return state, None
        snaps = [p.advance(state, n, outputs[(outputs > state.step)
                                             & (outputs <= state.step + n)])
                 for n in splits]
        return state, np.concatenate([s.extra[acc.key] for s in snaps])

    batch, bsnap = run(np.arange(m), [400])
    assert acc.rule is not None          # written out in the loops, not called
    chunked, csnap = run(np.arange(m), [150, 250])
    np.testing.assert_array_equal(batch.extra[acc.key], chunked.extra[acc.key])
    np.testing.assert_array_equal(bsnap, csnap)
    for i in (0, 7, 19):
        one, osnap = run(np.array([i]), [400])
        np.testing.assert_array_equal(one.extra[acc.key][0], batch.extra[acc.key][i])
        np.testing.assert_array_equal(osnap[:, 0], bsnap[:, i])
    generic, _ = run(np.arange(m), [400], generated=False)
    used = [0, 1] if name == "fli" else [0, 1, 2, 3, 4]
    a, b = batch.extra[acc.key][..., used], generic.extra[acc.key][..., used]
    # Round-off of the two steppers, grown along the chaotic orbits (the
    # deviation vectors' directions differ by ~1e-13 at t = 20).
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    fli = a[:, 0, 1] if name == "fli" else a[:, 0, 3]
    assert (fli >= a[:, 0, 0] - 1e-12).all()     # the supremum of ln‖w‖ bounds its last value


@pytest.mark.parametrize("indicator, options", [
    ("lyapunov", {}),
    ("gali", {"k": (2, 4)}),
])
def test_sparse_renormalisation_gives_every_step_values(indicator, options):
    """Renormalising on the adaptive schedule gives the exponents and GALIs
    of renormalising every step, to round-off (QR and GS are exact changes
    of basis of the same span; only round-off differs)."""
    x0 = _hh_orbits(1, spread=0.0)[0]
    kw = dict(t_end=2e3, tau=0.05, t_out=np.array([500.0, 1000.0, 2000.0]), seed=2, **options)
    sparse = varint.run(HH, x0, indicator, **kw)
    every = varint.run(HH, x0, indicator, renormalize_every=1, **kw)
    if indicator == "lyapunov":
        # Round-off differences, grown along this chaotic orbit by e^{χ t}
        # in the smallest exponents' directions: 1e-11 at t = 2000.
        assert np.abs(np.asarray(sparse.exponents) - np.asarray(every.exponents)).max() < 1e-10
    else:
        for order in (2, 4):
            a, b = np.asarray(sparse.gali[order]), np.asarray(every.gali[order])
            # Round-off of unit vectors' volumes (1e-16 each, grown along
            # the chaotic orbit) is absolute: 1e-14 on a GALI of 1e-9.
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-13)


def test_fixed_interval_option():
    """renormalize_every=n renormalises every n steps; a float is a time."""
    x0 = _hh_orbits(1, spread=0.0)[0]
    kw = dict(t_end=500.0, tau=0.05, t_out=np.array([500.0]), seed=2)
    ref = varint.run(HH, x0, "lyapunov", renormalize_every=1, **kw)
    for every in (10, 2.5):
        r = varint.run(HH, x0, "lyapunov", renormalize_every=every, **kw)
        assert np.abs(np.asarray(r.exponents) - np.asarray(ref.exponents)).max() < 1e-12
    for bad in (0, -3, float("nan"), True):
        with pytest.raises(ValueError, match="renormalize_every"):
            varint.run(HH, x0, "lyapunov", renormalize_every=bad, **kw)


def test_generated_module_is_written_to_the_cache(tmp_path, monkeypatch):
    """The generated module goes to <cache dir>/kernels under the hash of
    what it is made from; a new process loads that file without emitting
    the source or writing the file again."""
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(G, "_LOADED", {})
    p = TangentMapPropagator(HH, 0.05, Renorm.QR, scheme="SBAB2C")
    module = p._stepper(1)
    files = list((tmp_path / "kernels").glob("varint_stepper_*.py"))
    assert len(files) == 1 and "def orbit(" in files[0].read_text()
    assert TangentMapPropagator(HH, 0.05, Renorm.QR, scheme="SBAB2C")._stepper(1) is module
    mtime = files[0].stat().st_mtime_ns
    monkeypatch.setattr(G, "_LOADED", {})      # as in a new process,
    monkeypatch.setattr(G, "_source", lambda *args: pytest.fail("source emitted again"))
    # with a new model (a model remembers its steppers)
    again = TangentMapPropagator(HenonHeiles(), 0.05, Renorm.QR, scheme="SBAB2C")._stepper(1)
    assert again is not module and again.__file__ == str(files[0])
    assert files[0].stat().st_mtime_ns == mtime
    assert X.symbolic_fits(HH, 4) and not X.symbolic_fits(HH, X.SYMBOLIC_MAX_VALUES)


def test_too_many_vectors_for_straight_line_code_use_the_generic_stepper():
    """FPU n = 8 with the full spectrum (16 vectors: beyond the generated
    stepper's size) runs on the generic stepper, outputs and all, and its
    16 finite-time exponents sum to zero (the tangent map preserves volume:
    Σ ln R_ii = ln det = 0 at every t)."""
    model, x0 = varint.paper_orbit("R3")
    assert X.symbolic_fits(model, 1) and not X.symbolic_fits(model, 16)
    r = varint.lyapunov_spectrum(model, x0, t_end=200.0, t_out=np.array([100.0, 200.0]))
    x = np.asarray(r.exponents)
    assert x.shape == (2, 16) and np.abs(x.sum(axis=1)).max() < 1e-12


def test_renormalised_copies_are_the_steppers_renormalisation():
    """Snapshots read between renormalisations are renormalised by the
    steppers' own Gram–Schmidt: Q R = W with R's diagonal the stretching
    (as NumPy's QR with a positive diagonal, to round-off), and a failed
    row reads NaN."""
    from varint.state import renormalized_copy

    rng = np.random.default_rng(4)
    W = rng.standard_normal((50, 6, 3)) * rng.uniform(1e-3, 1e3, (50, 1, 3))
    acc_m, acc_e = rng.uniform(0.5, 1.0, (50, 3)), rng.integers(-600, 600, (50, 3))
    W[7, :, 1] = np.inf
    Q, m, e = renormalized_copy(W, acc_m, acc_e, Renorm.QR)
    q, r = np.linalg.qr(np.delete(W, 7, axis=0))
    d = np.diagonal(r, axis1=1, axis2=2)
    ok = np.delete(np.arange(50), 7)
    assert np.abs(Q[ok] - q * np.sign(d)[:, None, :]).max() < 1e-12
    growth = np.log(m) + e * np.log(2.0)
    want = np.log(acc_m[ok]) + acc_e[ok] * np.log(2.0) + np.log(np.abs(d))
    assert np.abs(growth[ok] - want).max() < 1e-12
    assert np.isnan(Q[7]).all() and np.isnan(m[7]).all()
    # Unit columns, each stretching its own norm.
    U, m1, e1 = renormalized_copy(W[ok], acc_m[ok], acc_e[ok], Renorm.NORMALIZE)
    norms = np.linalg.norm(W[ok], axis=1)
    assert np.abs(U - W[ok] / norms[:, None, :]).max() < 1e-15
    assert np.abs(np.log(m1) + e1 * np.log(2.0)
                  - (np.log(acc_m[ok]) + acc_e[ok] * np.log(2.0) + np.log(norms))).max() < 1e-12
    # The inputs are not touched.
    assert np.isinf(W[7, :, 1]).all()


def test_lane_layout_round_trip():
    """Orbits into SIMD lanes and back: every active row, padding dropped,
    inactive rows untouched, for contiguous and strided arrays."""
    from varint.methods.tm import _Lanes

    rng = np.random.default_rng(2)
    active = np.sort(rng.choice(40, 27, replace=False))
    lanes = _Lanes(active, 8)
    for a in (rng.standard_normal((40, 4, 3)), rng.integers(0, 99, (40, 2)),
              rng.standard_normal((40, 2))[:, 1], np.zeros((40, 4, 0))):
        soa = lanes.soa(a)
        assert soa.shape == (lanes.blocks,) + a.shape[1:] + (8,)
        rows = np.moveaxis(soa, -1, 1).reshape((lanes.blocks * 8,) + a.shape[1:])
        assert np.array_equal(rows[:27], a[active])
        target = np.zeros_like(a)
        lanes.put(soa, target)
        assert np.array_equal(target[active], a[active])
        assert not np.delete(target, active, axis=0).any()


def test_lane_outputs_back_into_rows():
    """The lanes' copies at outputs (blocks, S, ..., lanes) back into the
    active orbits' rows of (S, M, ...): each output's row of each active
    orbit, padding dropped, inactive rows untouched, for contiguous
    (compiled) and strided (NumPy) targets, floats and integers."""
    from varint.methods.tm import _Lanes

    rng = np.random.default_rng(3)
    active = np.sort(rng.choice(40, 27, replace=False))
    lanes = _Lanes(active, 8)
    for shape, draw in (((5, 40, 4, 3), rng.standard_normal), ((5, 40, 2), rng.standard_normal),
                        ((5, 40, 1), lambda s: rng.integers(0, 99, s))):
        rows = draw(shape)
        # The lanes' layout, by index: row active[i] is lane i % 8 of block i // 8.
        src = np.full((lanes.blocks, shape[0]) + shape[2:] + (8,), -1, dtype=rows.dtype)
        for i, row in enumerate(active):
            src[i // 8, ..., i % 8] = rows[:, row]
        for target in (np.zeros_like(rows), np.zeros(shape[:1] + (2 * shape[1],) + shape[2:],
                                                      dtype=rows.dtype)[:, ::2]):
            lanes.put_outputs(src, target)
            assert np.array_equal(target[:, active], rows[:, active])
            assert not np.delete(target, active, axis=1).any()


def test_a_built_in_models_symbolic_facts_are_read_from_the_cache(monkeypatch, tmp_path):
    """Whether a built-in model gets a generated stepper, and the key of its
    potential, are kept beside the steppers under its description: a new
    process running it builds no SymPy expression. Another description
    (here other parameters) is another file; an unreadable file is made
    again."""
    from varint.models import FPUT

    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(X, "_FACTS", {})
    model = FPUT(6, 0.25, 1.0)
    fits, key = X.symbolic_fits(model, 1), X.model_key(model)
    V, _, n, planar, extra = X._FORMS[key]
    assert fits and n == 6 and planar is None and extra is None and "Symbol('q5')" in sympy.srepr(V)
    files = list((tmp_path / "kernels").glob("varint_model_*.json"))
    assert len(files) == 1

    def sympy_asked(model):
        raise AssertionError("SymPy asked")

    monkeypatch.setattr(X, "_FACTS", {})              # as in a new process
    monkeypatch.setattr(X, "_facts_now", sympy_asked)
    assert X.symbolic_fits(FPUT(6, 0.25, 1.0), 1) and X.model_key(FPUT(6, 0.25, 1.0)) == key
    with pytest.raises(AssertionError, match="SymPy asked"):
        X.symbolic_fits(FPUT(6, 0.5, 1.0), 1)         # another alpha: its own facts
    files[0].write_text("{not json")
    monkeypatch.setattr(X, "_FACTS", {})
    with pytest.raises(AssertionError, match="SymPy asked"), \
            pytest.warns(CacheDirWarning, match="signature"):
        X.symbolic_fits(FPUT(6, 0.25, 1.0), 1)


def test_a_users_own_model_class_is_asked_for_its_symbolic_form_every_process(monkeypatch):
    """Only varint's own classes have their facts cached: the code behind a
    user's class (and what it imports) is not known, so a change to it
    could not be seen."""
    class Stiffer(HenonHeiles):
        pass

    asked = []
    monkeypatch.setattr(X, "_facts_now", lambda model: asked.append(model) or (False, None))
    assert not X.symbolic_fits(Stiffer(), 1) and len(asked) == 1


@pytest.mark.parametrize("name", ["megno", "fli"])
def test_a_rules_logarithm_is_called_by_one_orbit_and_inlined_in_the_lanes(name):
    """One orbit calls the logarithm of MEGNO's and FLI's rules
    (``vlog_called``: numba inlining its IR cost compile time off the hot
    path), the lanes inline it (``vlog``: their loop vectorises);
    ``test_inline_accumulators_lanes_orbit_chunks_and_generic`` checks that
    both give the same bits."""
    import re

    from varint.indicators.megno import FLI_ACCUMULATOR, MEGNO_ACCUMULATOR
    from varint.schemes import DRIFT, get_scheme, stage_arrays

    acc = {"megno": MEGNO_ACCUMULATOR, "fli": FLI_ACCUMULATOR}[name]
    model = HenonHeiles()
    kinds, _, hc = stage_arrays(get_scheme("SBAB2C"), 0.05)
    corrected = (hc != 0.0) & (kinds != DRIFT)
    plan = G.Plan(tuple(int(v) for v in kinds), tuple(bool(c) for c in corrected), 1,
                  G._accumulator_id(acc))
    key = X.model_key(model)
    X.ensure_form(model, key)
    source = G.generated_source(X.expressions(key), plan, acc)
    orbit = source[source.index("def orbit("):source.index("def batch_serial(")]
    lanes = source[source.index("def lanes("):source.index("def blocks_serial(")]
    assert re.search(r"\bvlog_called\(", orbit) and not re.search(r"\bvlog\(", orbit)
    assert re.search(r"\bvlog\(", lanes)
