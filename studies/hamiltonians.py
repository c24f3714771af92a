"""Hamiltonians beyond ½pᵀM⁻¹p + V(q): the restricted three-body problem, a
rotating Ferrers bar, a magnetic bottle and general H(q, p) — published
values, work–precision of every method, classification agreement, and the
targets of issue 29 against heyoka and galpy.

Parts (``--part``, several separated by commas; all by default):

``published``
    Values from the literature reproduced: the Jacobi constants of the
    Earth–Moon Lagrange points (Koon, Lo, Marsden & Ross 2011, Sect. 2.4:
    3.1883, 3.1722, 3.0121, 2.9880) and C(L4) = 3 − μ(1 − μ); Arenstorf's
    orbit (Hairer, Nørsett & Wanner 1993, Sect. II.0, eq. 0.1, Fig. 0.1)
    closing after its period 17.0652165601579625588917206249 (the distance
    from its start, by heyoka and by varint's methods); the Ferrers bar's
    potential against galpy's ``FerrersPotential`` (where galpy installs).
``maps``
    FLI and MEGNO maps of the restricted three-body problem: Sun–Jupiter
    μ = 0.000954, the section y = 0 with ẏ > 0 at Jacobi constant C = 3.05,
    on a grid of (x, p_x) (x ∈ [0.3, 0.85], p_x ∈ [−0.3, 0.3]; 40 × 30, of
    which the allowed points are the orbits), t = 1000 (≈ 160 periods of
    Jupiter). varint's ``chaos_map`` with its defaults (no τ, no scheme)
    against heyoka's ``taylor_adaptive_batch`` (batch 8, its own
    variational equations from the same expression, tolerances 1e-6 … 1e-12,
    normalising every 10 time units; ``studies/bench_peers.py`` drives it as
    its experts would), one thread each, interleaved, the minimum of the
    repeats (wall time, or with ``--maps-clock cpu`` the process's CPU
    time, which leaves the other jobs of a loaded machine out). The
    reference is heyoka at tol 1e-15 normalising every time unit; orbits are classified by the antimode of the reference's
    distribution of log10(value); agreement is the fraction classified as
    the reference classifies them. Target: varint's defaults ≥ 3× faster
    per thread than heyoka batch 8 at equal agreement (the cheapest heyoka
    tolerance whose agreement reaches varint's).
``bar``
    The largest Lyapunov exponent of the rotating bar's named orbits
    (:data:`varint.models.bar.BAR_ORBITS`): varint's ``lyapunov_spectrum``
    (defaults; SRKN14a at τ = 0.8 … 0.05, ABA864 at thirteen steps τ = 0.5 …
    0.1, each a whole number of steps to t_end)
    against galpy's ``Orbit.lyapunov`` and AGAMA's ``orbit`` in the frame
    rotating with ``Omega`` (where they install), at equal accuracy of X1
    against a tight reference (varint, ABA864 at τ = 0.005). AGAMA is
    driven as its documentation says: ``lyapunov=True`` (its λ·T_orb,
    fitted to the growth of one deviation vector, divided by its
    ``Tcirc``: an estimate of the asymptotic exponent, 0 when it sees no
    exponential growth, so not the finite-time X1) and ``der=True`` (the
    six deviation vectors of its variational equations, whose tangent map
    applied to the common deviation vector gives X1 = ln|δx(t)|/t, at
    accuracies 1e-6, 1e-9, 1e-12; AGAMA's state in the rotating frame is
    varint's (q, p), checked in ``tests/studies``). PyPI's ``agama`` (1.0.0)
    is a stub whose setup downloads the source from GitHub: without the
    network it does not install; built from a snapshot of its repository
    (``python setup.py install`` with Debian's libgsl-dev) it does.
    Target: ≥ 3× galpy and AGAMA.

``precision``
    Work–precision of every method on each system, orbit and one tangent
    vector (``lyapunov_spectrum`` with one exponent from the same unit
    vector): the error at t_end is the larger of the orbit's (max norm)
    and of the vector's accumulated log-stretching, against heyoka's Taylor
    method in extended precision (long double, tol ε); the cost is the
    process's CPU time (``--precision-clock cpu``, the default: one thread,
    so other jobs of a loaded machine stay out of it) or the wall time
    (``wall``), interleaved, minimum of the repeats. Systems and
    contenders: the restricted three-body problem (Sun–Jupiter, a regular
    orbit, t = 100): the rotating-frame split (SRKN14a, ABA864, s11odr6),
    the termwise split (s11ABC6), Gauss–Legendre and Tao's method on the
    same H forced general, heyoka and DOP853; the magnetic bottle (regular
    orbit): its termwise four-part split, Gauss–Legendre, Tao, heyoka,
    DOP853; a relativistic T(p) + V(q): s11odr6, SRKN14a, Gauss–Legendre,
    heyoka; and two general H without exploitable structure (Hénon–Heiles
    with the couplings (x p_y)²/8 + x y p_x/4, and Tao's (q² + 1)(p² + 1)/2):
    Gauss–Legendre (GL4, GL6, GL8), Tao (orders 4 and 6: Yoshida's triple
    jumps ABC4_Y, ABC6_Y of Tao's map, ω = 20: schemes TAO4, TAO6 of
    ``method="tm"``), heyoka, DOP853.
    The general systems answer two questions of issue 29: which of Tao's
    method and Gauss–Legendre is cheaper at equal accuracy (the default of
    general models), and the target that varint stays within 2× of heyoka
    at equal accuracy for errors ≥ 1e-8 (heyoka's cost read off its
    cost–error front at varint's errors, log–log interpolated).

Usage: ``python studies/hamiltonians.py [--quick] [--out DIR] [--part maps,bar,...]
[--repeats N] [--galpy-rtols 1e-6,1e-9] [--galpy-stored JSON] [--precision-clock cpu|wall] [--systems general]``. State the machine load (``uptime``, recorded in the JSON)
with every figure.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
import warnings
from pathlib import Path

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.bench_peers import (HeyokaMap, agreement, antimode, chaotic, cost_at, interleaved,
                                 pareto, seeded_vectors)
from studies.common import Claims, parse_args, save_csv, save_json
from varint.models.bar import BAR_ORBITS, RotatingBar, bar_orbit
from varint.models.cr3bp import (ARENSTORF_PERIOD, CR3BP, EARTH_MOON_MU, SUN_JUPITER_MU,
                                 cr3bp_orbit)

PARTS = ("published", "maps", "bar", "precision")
REPEATS = 3
#: The map: Sun–Jupiter section y = 0, ẏ > 0 at C = 3.05.
JACOBI = 3.05
MAP_X = (0.3, 0.85)
MAP_PX = (-0.3, 0.3)
MAP_TOLS = (1e-6, 1e-8, 1e-10, 1e-12)
REF_TOL = 1e-15
REF_EVERY = 1.0
#: varint's steps to t = 100 in the bar race (scaled to a shorter t_end):
#: SRKN14a at τ = 0.8 … 0.05 and ABA864 at τ = 0.5 … 0.1 (:func:`bar_case`).
BAR_SRKN_STEPS = (125, 250, 500, 1000, 2000)
BAR_ABA_STEPS = (200, 230, 250, 265, 300, 350, 400, 460, 530, 610, 700, 800, 1000)
#: AGAMA's relative accuracies of its DOP853 orbit (and GL4 variational) steps.
AGAMA_ACCURACIES = (1e-6, 1e-9, 1e-12)
#: galpy's relative tolerances of Orbit.lyapunov (``--galpy-rtols``).
GALPY_RTOLS = (1e-6, 1e-9)
EVERY = 10.0
BATCH = 8
#: Koon, Lo, Marsden & Ross (2011), Sect. 2.4: Earth–Moon, μ = 0.01215.
KOON_JACOBI = {"L1": 3.1883, "L2": 3.1722, "L3": 3.0121, "L4": 2.9880}


def load():
    """The machine's load averages (1, 5, 15 min), recorded with every
    timing."""
    return list(os.getloadavg())


# -- published values -------------------------------------------------------------------
def published_case(quick):
    rows = []
    m = CR3BP(EARTH_MOON_MU)
    points = m.lagrange_points()
    for name, value in KOON_JACOBI.items():
        ours = float(m.jacobi_at(*points[name]))
        rows.append({"quantity": f"C({name}), Earth–Moon", "published": value, "ours": ours,
                     "difference": ours - value, "source": "Koon et al. 2011, Sect. 2.4"})
    mu = EARTH_MOON_MU
    rows.append({"quantity": "C(L4) − (3 − μ(1 − μ))", "published": 0.0,
                 "ours": float(m.jacobi_at(*points["L4"])) - (3 - mu * (1 - mu)),
                 "source": "exact"})
    model, x0 = cr3bp_orbit("arenstorf")
    closing = {}
    from varint.baselines.taylor import heyoka_system
    import heyoka as hy

    system, _ = heyoka_system(model.symbolic())
    ta = hy.taylor_adaptive(system, x0.copy(), tol=1e-16)
    ta.propagate_until(ARENSTORF_PERIOD)
    closing["heyoka tol 1e-16"] = float(np.abs(ta.state - x0).max())
    for scheme, n in (("ABA864", 20000 if quick else 80000), ("SRKN14a", 20000 if quick
                                                                 else 80000)):
        r = varint.integrate(model, x0, ARENSTORF_PERIOD, tau=ARENSTORF_PERIOD / n,
                             scheme=scheme, t_out=[ARENSTORF_PERIOD], energy_tol=math.inf)
        closing[f"{scheme}, τ = T/{n}"] = float(np.abs(r.state - x0).max())
    for name, value in closing.items():
        rows.append({"quantity": f"Arenstorf orbit: |x(T) − x(0)|, {name}", "published": 0.0,
                     "ours": value, "source": "Hairer, Nørsett & Wanner 1993, eq. 0.1"})
    galpy = _galpy_potential_check()
    if galpy is not None:
        rows.append(galpy)
    return rows


def _galpy_potential_check():
    """The bar model's potential against galpy's at a few points (galpy's
    FerrersPotential takes axis ratios b/a, c/a; G = 1 in natural units)."""
    try:
        from galpy.potential import (FerrersPotential, MiyamotoNagaiPotential,
                                     PlummerPotential, evaluatePotentials)
    except ImportError:
        return None
    m = RotatingBar()
    pot = _galpy_bar(FerrersPotential, MiyamotoNagaiPotential, PlummerPotential)
    worst = 0.0
    for q in ([1.0, 0.5, 0.2], [5.0, 1.4, 0.3], [7.0, 2.0, 1.0], [0.3, 4.0, -2.0]):
        R, phi = math.hypot(q[0], q[1]), math.atan2(q[1], q[0])
        theirs = evaluatePotentials(pot, R, q[2], phi=phi, t=0.0)
        ours = float(m.potential(np.array(q)))
        worst = max(worst, abs(ours - theirs) / abs(theirs))
    return {"quantity": "RotatingBar potential vs galpy (largest relative difference, 4 "
                        "points)", "published": 0.0, "ours": worst, "source": "galpy"}


def _galpy_bar(FerrersPotential, MiyamotoNagaiPotential, PlummerPotential):
    return [MiyamotoNagaiPotential(amp=0.82, a=3.0, b=1.0), PlummerPotential(amp=0.08, b=0.4),
            FerrersPotential(amp=0.1, a=6.0, b=0.25, c=0.1, omegab=0.054)]


# -- the map target -----------------------------------------------------------------------
def map_grid(quick):
    model = CR3BP(SUN_JUPITER_MU)
    nx, ny = (10, 8) if quick else (40, 30)
    return model, model.section_grid(JACOBI, np.linspace(*MAP_X, nx), np.linspace(*MAP_PX, ny))


def maps_case(quick, repeats, clock=time.perf_counter):
    """The map rows: per indicator, varint's defaults and heyoka batch 8 at
    each tolerance, with agreement and seconds by ``clock`` (module
    docstring; ``time.process_time``: every contender runs one thread)."""
    model, grid = map_grid(quick)
    X = grid.states
    t_end = 200.0 if quick else 1000.0
    tols = MAP_TOLS[::2] if quick else MAP_TOLS
    W0 = seeded_vectors(model.dim, 1, len(X))
    rows, summary = [], {}
    numba.set_num_threads(1)
    import heyoka as hy

    hy.set_nthreads(1)
    for ind in ("fli", "megno"):
        ref = HeyokaMap(model, ind, "var_ode_sys", BATCH, REF_TOL, every=REF_EVERY)
        values_ref = ref.run(X, W0, t_end)
        threshold, rule = antimode(values_ref)
        truth = chaotic(ind, values_ref, threshold)
        # One untimed call compiles varint's kernels, as building each
        # HeyokaMap below compiles heyoka's, and names the scheme and step
        # the defaults choose: the second varint contender runs them given,
        # without the pilot, which splits the defaults' time into pilot and
        # run (the profile of issue 29's remaining gap).
        warm = varint.chaos_map(model, grid, ind, t_end=t_end, progress=False)
        chosen = {"scheme": warm.provenance.method_options["scheme"]["name"],
                  "tau": warm.provenance.tau}
        tasks = {"varint defaults": lambda ind=ind: varint.chaos_map(
            model, grid, ind, t_end=t_end, progress=False),
            "varint, the defaults' scheme and τ given": lambda ind=ind, given=chosen: (
                varint.chaos_map(model, grid, ind, t_end=t_end, progress=False, **given))}
        for tol in tols:
            hm = HeyokaMap(model, ind, "var_ode_sys", BATCH, tol, every=EVERY)
            tasks[f"heyoka batch {BATCH}, tol {tol:g}"] = (
                lambda hm=hm: hm.run(X, W0, t_end))
        best, outs = interleaved(tasks, repeats, clock=clock)
        for label, seconds in best.items():
            out = outs[label]
            values = out.values if hasattr(out, "values") else out
            row = {"indicator": ind, "contender": label, "seconds": seconds,
                   "agreement": agreement(ind, np.asarray(values), truth, threshold),
                   "orbits": len(X), "t_end": t_end, "threshold": threshold, "rule": rule}
            if hasattr(out, "provenance"):
                row["config"] = (f"{out.provenance.method_options['scheme']['name']}, "
                                 f"τ = {out.provenance.tau:.4g}")
                # Seconds of the last call's pilot and run (its compile is 0:
                # warmed above).
                row["timing"] = out.provenance.timing
            rows.append(row)
        summary[ind] = _equal_agreement([r for r in rows if r["indicator"] == ind])
        print(f"{ind}: chaotic fraction {truth.mean():.3f}; " + "; ".join(
            f"{r['contender']}: {r['seconds']:.3g} s, agree {r['agreement']:.4f}"
            for r in rows if r["indicator"] == ind), flush=True)
        print(f"  equal agreement: {summary[ind]}", flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return rows, summary


def _equal_agreement(rows):
    """varint's time against the cheapest heyoka configuration whose
    agreement reaches varint's (or the best heyoka, if none does)."""
    ours = next(r for r in rows if r["contender"] == "varint defaults")
    peers = [r for r in rows if not r["contender"].startswith("varint")]
    meeting = [r for r in peers if r["agreement"] >= ours["agreement"]]
    peer = (min(meeting, key=lambda r: r["seconds"]) if meeting
            else max(peers, key=lambda r: r["agreement"]))
    return {"varint_seconds": ours["seconds"], "varint_agreement": ours["agreement"],
            "heyoka": peer["contender"], "heyoka_seconds": peer["seconds"],
            "heyoka_agreement": peer["agreement"], "speedup": peer["seconds"] / ours["seconds"],
            "heyoka_reaches": bool(meeting)}


# -- the bar target -----------------------------------------------------------------------
def bar_case(quick, repeats, galpy_rtols=GALPY_RTOLS, clock=time.perf_counter,
             galpy_stored=None):
    """X1 of the named bar orbits: varint (defaults, and SRKN14a and ABA864
    at a few steps), galpy's Orbit.lyapunov (at ``galpy_rtols``: minutes per call;
    none runs no galpy) and AGAMA, error against a tight reference. ``clock``:
    wall time, or ``time.process_time`` (each contender runs one thread:
    its CPU time leaves out the waits for other jobs of a loaded machine).
    ``galpy_stored``: the path of an earlier ``hamiltonians_bar.json`` whose
    galpy rows (:func:`stored_galpy_rows`) stand in for running galpy again
    (its calls take minutes each; its X1 does not depend on varint's code,
    and its error is taken against this run's reference)."""
    t_end = 20.0 if quick else 100.0
    rows = []
    try:
        import galpy  # noqa: F401
        have_galpy = True
    except ImportError:
        have_galpy = False
    agama_potential = _agama_bar()
    # Every contender starts from galpy's default deviation vector, equal
    # components (at t = 0 the rotating and inertial frames coincide, and
    # (δq, δp) in the rotating frame is (δx, δv) rotated: the same norm).
    w0 = np.full((6, 1), 1 / math.sqrt(6))
    for name in BAR_ORBITS:
        model, x0 = bar_orbit(name)
        reference = varint.lyapunov_spectrum(model, x0, t_end, tau=0.005, scheme="ABA864",
                                             deviations=w0, t_out=[t_end])
        x1_ref = float(reference.exponents[-1, 0])
        tasks = {"varint defaults": lambda model=model, x0=x0: varint.lyapunov_spectrum(
            model, x0, t_end, deviations=w0, t_out=[t_end])}
        # The default scheme (order 6, 14 kicks a step) and ABA864 (order
        # (8, 6, 4), 7 kicks), the cheapest at every accuracy of bar25's
        # sweep of the two-part schemes without corrector (ABA1064,
        # ABAH864, FR4, S9ODR6, S11ODR6, S15ODR8 need more kicks for the
        # same error; studies/results/bar25/bar_scheme_sweep.json), all on
        # the bar's generated stepper. Whole numbers of steps to t_end: a
        # τ that does not divide it ends the run a fraction of a step away
        # (τ = 0.45: t = 99.9), an error of ~1e-4 in X1 that is not the
        # scheme's. ABA864's ladder of ~15 % steps (and the race's earlier τ = 0.4)
        # brackets AGAMA's errors.
        for scheme, counts in (("SRKN14a", BAR_SRKN_STEPS), ("ABA864", BAR_ABA_STEPS)):
            for count in counts:
                tau = t_end / max(1, round(count * t_end / 100.0))
                tasks[f"varint {scheme} τ = {tau:.4g}"] = (
                    lambda model=model, x0=x0, tau=tau, scheme=scheme: varint.lyapunov_spectrum(
                        model, x0, t_end, tau=tau, scheme=scheme, deviations=w0,
                        t_out=[t_end]))
        if agama_potential is not None:
            tasks["AGAMA lyapunov=True (its fitted λ)"] = (
                lambda x0=x0: _agama_lyapunov(agama_potential, x0, t_end))
            for accuracy in AGAMA_ACCURACIES:
                tasks[f"AGAMA der=True accuracy {accuracy:g}"] = (
                    lambda x0=x0, accuracy=accuracy: _agama_x1(agama_potential, x0, w0[:, 0],
                                                               t_end, accuracy))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            best, outs = interleaved(tasks, 1 if quick else repeats, clock=clock)
            if have_galpy and galpy_rtols and galpy_stored is None:
                # Minutes per call: timed once each (the load's noise is small
                # against it), by the race's clock.
                for rtol in galpy_rtols:
                    label = f"galpy lyapunov rtol {rtol:g}"
                    t0 = clock()
                    outs[label] = _galpy_lyapunov(x0, w0[:, 0], t_end, rtol)
                    best[label] = clock() - t0
                label = "galpy finite differences of its orbits (ε = 1e-6)"
                t0 = clock()
                outs[label] = _galpy_finite_difference(x0, w0[:, 0], t_end)
                best[label] = clock() - t0
        for label, seconds in best.items():
            out = outs[label]
            x1 = float(out.exponents[-1, 0]) if hasattr(out, "exponents") else float(out)
            rows.append({"orbit": name, "contender": label, "seconds": seconds, "x1": x1,
                         "x1_reference": x1_ref, "error": abs(x1 - x1_ref), "t_end": t_end})
        if galpy_stored is not None:
            rows += [dict(r, x1_reference=x1_ref, error=abs(r["x1"] - x1_ref))
                     for r in stored_galpy_rows(galpy_stored, name, t_end)]
        print("; ".join(f"{r['contender']}: {r['seconds']:.3g} s, X1 {r['x1']:.5g} "
                        f"(error {r['error']:.1e})" for r in rows if r["orbit"] == name),
              flush=True)
    return rows


def stored_galpy_rows(path, orbit, t_end):
    """The galpy rows of ``orbit`` in the stored bar race ``path`` (a
    ``hamiltonians_bar.json``), each marked with where it comes from
    (``stored``: the file, its run's creation time, commit, load and
    clock). Refused where that run's horizon is not ``t_end``."""
    data = json.loads(Path(path).read_text())
    bar, prov = data["bar"], data.get("_provenance", {})
    origin = {"file": str(path), "created": prov.get("created"),
              "commit": prov.get("code", {}).get("commit"), "load": bar.get("load"),
              "clock": bar.get("clock", "wall")}
    rows = [dict(r, stored=origin) for r in bar["rows"]
            if r["orbit"] == orbit and r["contender"].startswith("galpy")]
    if not rows:
        raise SystemExit(f"--galpy-stored {path}: no galpy row of the {orbit!r} orbit")
    if any(r["t_end"] != t_end for r in rows):
        raise SystemExit(f"--galpy-stored {path}: its galpy rows run to t = {rows[0]['t_end']}, "
                         f"this race to t = {t_end}")
    return rows


def _galpy_orbit(x):
    """galpy's Orbit at the rotating frame's state ``x`` at t = 0."""
    from galpy.orbit import Orbit

    X, Y, Z, vx, vy, vz = x
    R, phi = math.hypot(X, Y), math.atan2(Y, X)
    return Orbit([R, (X * vx + Y * vy) / R, (X * vy - Y * vx) / R, Z, vz, phi])


def _galpy_finite_difference(x0, w0, t_end, eps=1e-6):
    """X1 at t_end from two galpy orbits started ±ε w0 apart (galpy's
    integrator and force in C; the inertial and rotating frames' norms of a
    deviation agree): what galpy's own orbits say its Lyapunov exponent is."""
    from galpy.potential import FerrersPotential, MiyamotoNagaiPotential, PlummerPotential

    pot = _galpy_bar(FerrersPotential, MiyamotoNagaiPotential, PlummerPotential)
    ts = np.linspace(0.0, t_end, int(t_end) + 1)
    ends = []
    for sign in (1.0, -1.0):
        o = _galpy_orbit(x0 + sign * eps * w0)
        o.integrate(ts, pot, method="dop853_c")
        t = ts[-1]
        ends.append(np.array([o.x(t), o.y(t), o.z(t), o.vx(t), o.vy(t), o.vz(t)]))
    return math.log(np.linalg.norm(ends[0] - ends[1]) / (2 * eps)) / t_end


def _agama_bar():
    """AGAMA's potential of the bar model (:data:`varint.models.bar.SPA02`:
    its Ferrers bar takes the axis ratios b/a, c/a), or None where AGAMA
    does not install."""
    try:
        import agama
    except ImportError:
        return None
    from varint.models.bar import SPA02

    # One thread, as every contender of the race: with its default OpenMP
    # threads on a loaded 2-core machine AGAMA's single orbit ran 2-6x
    # slower (studies/results/bar20/race_*_agama_default_threads).
    agama.setNumThreads(1)
    a, b, c = SPA02["axes"]
    return agama.Potential(
        {"type": "MiyamotoNagai", "mass": SPA02["disc_mass"], "scaleRadius": SPA02["disc_a"],
         "scaleHeight": SPA02["disc_b"]},
        {"type": "Plummer", "mass": SPA02["bulge_mass"], "scaleRadius": SPA02["bulge_radius"]},
        {"type": "Ferrers", "mass": SPA02["bar_mass"], "scaleRadius": a, "axisRatioY": b / a,
         "axisRatioZ": c / a})


def _agama_orbit(potential, x0, t_end, **options):
    """AGAMA's orbit from the rotating frame's state ``x0`` = (q, p) (its
    frame rotating with ``Omega`` takes the same state: checked in
    ``tests/studies``)."""
    import agama

    from varint.models.bar import SPA02

    return agama.orbit(potential=potential, ic=np.asarray(x0, dtype=float), time=t_end,
                       Omega=SPA02["omega"], dtype="float64", verbose=False, **options)


def _agama_x1(potential, x0, w0, t_end, accuracy):
    """X1 at t_end from AGAMA's tangent map (``der=True``: the derivatives of
    the state at t_end by each initial coordinate) applied to ``w0``."""
    dev = _agama_orbit(potential, x0, t_end, der=True, trajsize=2, accuracy=accuracy)[-1]
    return math.log(np.linalg.norm(np.asarray(dev)[:, -1, :].T @ w0)) / t_end


def _agama_lyapunov(potential, x0, t_end):
    """AGAMA's own Lyapunov estimate (``lyapunov=True``, default accuracy):
    its λ·T_orb over its T_orb (``Tcirc`` of the state)."""
    normalised = _agama_orbit(potential, x0, t_end, lyapunov=True)[0]
    return float(normalised) / float(potential.Tcirc(np.asarray(x0, dtype=float)))


def _galpy_lyapunov(x0, w0, t_end, rtol):
    """galpy's largest Lyapunov exponent of the bar orbit from the rotating
    frame's state ``x0`` (at t = 0 the frames coincide and p is the inertial
    velocity) and deviation vector ``w0``, with its default integrator
    (DOP853 in C; galpy falls back to SciPy's odeint for the Ferrers bar,
    whose C version cannot integrate the variational equations)."""
    from galpy.potential import FerrersPotential, MiyamotoNagaiPotential, PlummerPotential

    pot = _galpy_bar(FerrersPotential, MiyamotoNagaiPotential, PlummerPotential)
    o = _galpy_orbit(x0)
    ts = np.linspace(0.0, t_end, int(t_end) + 1)
    return o.lyapunov(ts, pot=pot, dxdv0=w0, rtol=rtol, atol=rtol * 1e-3)[-1]


# -- work–precision -----------------------------------------------------------------------
def _systems(quick):
    """name → (model, x0, t_end, contenders): contenders are (label, method,
    options, steps or tolerances)."""
    import sympy as sp

    from varint.models import bottle_orbit, cr3bp_orbit, from_hamiltonian

    t_scale = 0.2 if quick else 1.0
    systems = {}
    cr3bp, x_cr3bp = cr3bp_orbit("sun-jupiter-regular")
    general_cr3bp = from_hamiltonian(cr3bp.symbolic().H, cr3bp.symbolic().q,
                                     cr3bp.symbolic().p, structure="general", name="CR3BP general")
    terms_cr3bp = from_hamiltonian(cr3bp.symbolic().H, cr3bp.symbolic().q, cr3bp.symbolic().p,
                                   structure="terms", name="CR3BP termwise")
    taus = (0.2, 0.1, 0.05, 0.025)
    systems["CR3BP (Sun–Jupiter, regular)"] = (cr3bp, x_cr3bp, 100.0 * t_scale, [
        ("SRKN14a", "tm", {"scheme": "SRKN14a"}, taus, cr3bp),
        ("ABA864", "tm", {"scheme": "ABA864"}, taus, cr3bp),
        ("s11odr6", "tm", {"scheme": "s11odr6"}, taus, cr3bp),
        ("termwise s11ABC6", "tm", {"scheme": "s11ABC6"}, taus, terms_cr3bp),
        ("GL6 (general)", "tm", {"scheme": "GL6"}, taus, general_cr3bp),
        ("GL8 (general)", "tm", {"scheme": "GL8"}, taus, general_cr3bp),
        ("Tao4 (general)", "tm", {"scheme": "TAO4"}, tuple(t / 2 for t in taus),
         general_cr3bp)])
    bottle, x_bottle = bottle_orbit("adiabatic")
    general_bottle = from_hamiltonian(bottle.symbolic().H, bottle.symbolic().q,
                                      bottle.symbolic().p, structure="general",
                                      name="bottle general")
    taus = (0.4, 0.2, 0.1, 0.05)
    systems["magnetic bottle (adiabatic)"] = (bottle, x_bottle, 100.0 * t_scale, [
        ("termwise 4-part s11odr6", "tm", {}, taus, bottle),
        ("GL6 (general)", "tm", {"scheme": "GL6"}, taus, general_bottle),
        ("GL8 (general)", "tm", {"scheme": "GL8"}, taus, general_bottle),
        ("Tao4 (general)", "tm", {"scheme": "TAO4"}, tuple(t / 2 for t in taus),
         general_bottle)])
    x, y, px, py = sp.symbols("x y p_x p_y")
    hh = (x ** 2 + y ** 2) / 2 + x ** 2 * y - y ** 3 / 3
    rel = from_hamiltonian(sp.sqrt(1 + px ** 2 + py ** 2) + hh, [x, y], [px, py],
                           name="relativistic Hénon–Heiles")
    x_rel = np.array([0.1, 0.1, 0.3, 0.2])
    taus = (0.4, 0.2, 0.1, 0.05)
    systems["relativistic T(p) + V(q)"] = (rel, x_rel, 100.0 * t_scale, [
        ("s11odr6", "tm", {"scheme": "s11odr6"}, taus, rel),
        ("SRKN14a", "tm", {"scheme": "SRKN14a"}, taus, rel),
        ("ABA864", "tm", {"scheme": "ABA864"}, taus, rel),
        ("GL6 (general)", "tm", {"scheme": "GL6"}, taus, from_hamiltonian(
            rel.symbolic().H, [x, y], [px, py], structure="general"))])
    general = from_hamiltonian((px ** 2 + py ** 2) / 2 + hh + (x * py) ** 2 / 8 + x * y * px / 4,
                               [x, y], [px, py], name="coupled Hénon–Heiles (general)")
    x_general = np.array([0.1, 0.05, 0.2, 0.25])
    q, p = sp.symbols("q p")
    tao = from_hamiltonian((q ** 2 + 1) * (p ** 2 + 1) / 2, [q], [p], name="Tao's example")
    x_tao = np.array([-3.0, -1e-3])
    for name, model, x0, taus in (("general: coupled Hénon–Heiles", general, x_general,
                                   (0.4, 0.2, 0.1, 0.05)),
                                  ("general: Tao's (q² + 1)(p² + 1)/2", tao, x_tao,
                                   (0.1, 0.05, 0.025, 0.0125))):
        systems[name] = (model, x0, 100.0 * t_scale, [
            ("GL4", "tm", {"scheme": "GL4"}, taus, model),
            ("GL6", "tm", {"scheme": "GL6"}, taus, model),
            ("GL8", "tm", {"scheme": "GL8"}, taus, model),
            ("Tao4", "tm", {"scheme": "TAO4"}, tuple(t / 2 for t in taus), model),
            ("Tao6", "tm", {"scheme": "TAO6"}, tuple(t / 4 for t in taus), model)])
    return systems


def _peers(model):
    """heyoka (tolerances) and DOP853 (rtol) on the same expression."""
    out = [("heyoka", "taylor", {}, (1e-6, 1e-8, 1e-10, 1e-12, 1e-14), model)]
    if getattr(model, "symbolic", None) is not None and isinstance(model, RotatingBar):
        out = []
    out.append(("DOP853", "dop853", {}, (1e-6, 1e-8, 1e-10, 1e-12), model))
    return out


def _one(model, x0, t_end, method, options, knob):
    """One run, orbit and one tangent vector from the first unit vector
    (no energy tolerance unless ``options`` give one: ``energy_tol=None``,
    the default tolerance, for varint's defaults, whose step it sets)."""
    w0 = np.eye(model.dim)[:, :1]
    opts = {"energy_tol": math.inf, **options}
    if method == "taylor":
        opts.update(tol=knob)
        tau = 1.0
    elif method == "dop853":
        opts.update(rtol=knob, atol=knob * 1e-3)
        tau = 1.0
    else:
        tau = knob
    r = varint.lyapunov_spectrum(model, x0, t_end, tau=tau, method=method, deviations=w0,
                                 t_out=[t_end], progress=False, **opts)
    return r.state, float(r.exponents[-1, 0]) * t_end


def precision_case(quick, repeats, systems=None, peers=_peers, clock=time.perf_counter,
                   only=()):
    """The work–precision rows and per-system summaries (module docstring)
    of ``systems`` (name → (model, x0, t_end, contenders), as
    :func:`_systems`, whose are the default; ``only``: the names that
    contain one of these strings, or all) against ``peers(model)``
    (:func:`_peers` by default), timed by ``clock`` (wall time, or
    ``time.process_time``: every contender runs on one thread, so its CPU
    time leaves the other jobs of a loaded machine out);
    ``studies/general_h_heldout.py`` races its held-out Hamiltonians
    through it."""
    rows, summary = [], {}
    numba.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, (model, x0, t_end, contenders) in (
                _systems(quick) if systems is None else systems).items():
            if only and not any(o in name for o in only):
                continue
            ref = varint.lyapunov_spectrum(model, x0, t_end, tau=1.0, method="taylor",
                                           precision="extended",
                                           deviations=np.eye(model.dim)[:, :1], t_out=[t_end],
                                           energy_tol=math.inf, progress=False)
            x_ref, log_ref = ref.state, float(ref.exponents[-1, 0]) * t_end
            tasks = {}
            for label, method, options, knobs, m in contenders + peers(model):
                for knob in knobs:
                    # Compiled before the timing (a short run of the same kind;
                    # heyoka builds an integrator per tolerance).
                    _one(m, x0, min(t_end, 1.0), method, options, knob)
                    tasks[(label, knob)] = (
                        lambda m=m, method=method, options=options, knob=knob, x0=x0,
                        t_end=t_end: _one(m, x0, t_end, method, options, knob))
            best, outs = interleaved(tasks, 1 if quick else repeats, clock=clock)
            for (label, knob), seconds in best.items():
                state, log_growth = outs[(label, knob)]
                error = max(float(np.abs(state - x_ref).max()), abs(log_growth - log_ref))
                rows.append({"system": name, "contender": label, "knob": knob,
                             "seconds": seconds, "error": error, "t_end": t_end})
            summary[name] = _precision_summary([r for r in rows if r["system"] == name])
            print(name, summary[name], flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return rows, summary


def contender_fronts(rows):
    """Per contender of ``rows`` (the precision machinery's rows) its
    cost–error front, and heyoka's (empty where it did not run)."""
    fronts = {}
    for r in rows:
        fronts.setdefault(r["contender"], []).append((r["seconds"], r["error"]))
    fronts = {k: pareto(v) for k, v in fronts.items()}
    return fronts, fronts.get("heyoka", [])


def _precision_summary(rows, floor=1e-8):
    """Per contender its cost–error front; for each of varint's fronts, the
    ratio of heyoka's cost to its own at its errors ≥ ``floor`` (the
    smallest over those points: "within 2×" asks it to stay ≥ 0.5)."""
    fronts, heyoka = contender_fronts(rows)
    out = {}
    for label, front in fronts.items():
        if label in ("heyoka", "DOP853"):
            continue
        ratios = []
        for cost, err in front:
            if err < floor:
                continue
            theirs, how = cost_at(heyoka, err)
            if theirs is not None:
                ratios.append((err, theirs / cost, how))
        out[label] = {"front": front, "heyoka_over_varint": ratios,
                      "worst": min((r for _, r, _ in ratios), default=None)}
    return out


# -- claims -------------------------------------------------------------------------------
def bar_speedup(rows, peer):
    """How many times faster varint is than ``peer`` (the rows of one orbit)
    at equal accuracy, in the peer's most favourable configuration: for
    each of the peer's runs that gave a value, varint's cheapest run at
    least as accurate (None where none is); the smallest ratio, with both
    rows (AGAMA's ``lyapunov=True`` gives NaN when its fit cannot tell)."""
    ours = [r for r in rows if r["contender"].startswith("varint")]
    best = None
    for theirs in rows:
        # A non-finite error is stored as text (studies.common.save_json).
        if not (theirs["contender"].startswith(peer) and isinstance(theirs["error"], float)
                and math.isfinite(theirs["error"])):
            continue
        enough = [r for r in ours if r["error"] <= theirs["error"]]
        if not enough:
            return None, None, theirs
        fastest = min(enough, key=lambda r: r["seconds"])
        ratio = theirs["seconds"] / fastest["seconds"]
        if best is None or ratio < best[0]:
            best = (ratio, fastest, theirs)
    return best if best is not None else (None, None, None)


def _bar_claims(c, bar):
    """The bar target per orbit and peer (galpy's Orbit.lyapunov, AGAMA's
    orbit): :func:`bar_speedup` ≥ 3."""
    rows, load0 = bar["rows"], bar["load"][0]
    for orbit in sorted({r["orbit"] for r in rows}):
        mine = [r for r in rows if r["orbit"] == orbit]
        fd = next((r for r in mine if r["contender"].startswith("galpy finite")), None)
        for peer, prefix, note in (
                ("galpy", "galpy lyapunov",
                 "galpy's Orbit.lyapunov falls back to SciPy's odeint for the Ferrers bar"
                 + (f"; galpy's own orbits by finite differences: X1 = {fd['x1']:.5g} against "
                    f"the reference {fd['x1_reference']:.5g}" if fd else "")),
                ("AGAMA", "AGAMA",
                 "AGAMA's lyapunov=True fits an asymptotic λ (0 when it sees no exponential "
                 "growth), not the finite-time X1; its der=True tangent map gives X1")):
            ratio, ours, theirs = bar_speedup(mine, prefix)
            claim = (f"Bar orbit '{orbit}': X1 ≥ 3× faster than {peer} at equal accuracy "
                     "(issue 29)")
            if theirs is None:
                c.add(claim, paper="≥ 3×", ours=f"no {peer} run ({peer} not installed, or "
                      "galpy left out by --galpy-rtols '')", holds=None)
            elif ratio is None:
                c.add(claim, paper="≥ 3×", ours=f"no varint run as accurate as {theirs['contender']}"
                      f" (error {theirs['error']:.1e}); load {load0:.1f}", holds=False, note=note)
            else:
                stored = theirs.get("stored")
                where = ("" if not stored else
                         f" (stored run {stored['created']}, {stored['clock']} time, load "
                         f"{stored['load'][0]:.1f})")
                c.add(claim, paper="≥ 3×",
                      ours=f"{ratio:.3g}× ({ours['contender']} {ours['seconds']:.3g} s, X1 error "
                           f"{ours['error']:.1e}; {theirs['contender']} {theirs['seconds']:.3g} s"
                           f"{where}, error {theirs['error']:.1e}; the peer's most favourable "
                           f"run); load {load0:.1f}, {bar.get('clock', 'wall')} time",
                      holds=ratio >= 3,
                      note=note + ("" if ratio >= 3 else
                                   f". Measured below the target: {theirs['contender']} (adaptive "
                                   "steps) reaches this error in less time than varint's fixed "
                                   "steps (SRKN14a: 14 evaluations of the Ferrers bar's gradient "
                                   "and Hessian each; ABA864: 7) and its fixed cost per call"))


def claims(out, result):
    c = Claims("hamiltonians", out, source="own")
    if "published" in result:
        for r in result["published"]["rows"]:
            if r["quantity"].startswith("C(L") and "Earth" in r["quantity"]:
                c.add(f"{r['quantity']} as published", paper=f"{r['published']:.4f}",
                      ours=f"{r['ours']:.6f}", holds=abs(r["difference"]) < 5e-5)
            elif r["quantity"].startswith("Arenstorf"):
                c.add(f"{r['quantity']} (published period)", paper="0",
                      ours=f"{r['ours']:.2e}", holds=None)
    if "maps" in result:
        for ind, s in result["maps"]["summary"].items():
            c.add(f"CR3BP {ind.upper()} map with defaults ≥ 3× heyoka batch 8 per thread at "
                  "equal agreement with a tight reference (issue 29)", paper="≥ 3×",
                  ours=f"{s['speedup']:.2f}× ({s['heyoka']}: {s['heyoka_seconds']:.3g} s, "
                       f"agreement {s['heyoka_agreement']:.4f}; varint {s['varint_seconds']:.3g}"
                       f" s, agreement {s['varint_agreement']:.4f}); "
                       f"{result['maps'].get('clock', 'wall')} time, load "
                       f"{result['maps']['load'][0]:.1f}",
                  holds=s["speedup"] >= 3 and s["heyoka_reaches"],
                  note="" if s["speedup"] >= 3 else "measured below the target")
    if "bar" in result:
        _bar_claims(c, result["bar"])
    if "precision" in result:
        for system, summary in result["precision"]["summary"].items():
            if not system.startswith("general"):
                continue
            worst = {k: v["worst"] for k, v in summary.items() if v["worst"] is not None}
            if not worst:
                continue
            best_label = max(worst, key=worst.get)
            c.add(f"{system}: orbit + tangent within 2× of heyoka at equal accuracy for errors "
                  "≥ 1e-8 (issue 29)", paper="heyoka/varint ≥ 0.5",
                  ours=", ".join(f"{k}: {v:.3g}" for k, v in sorted(worst.items()))
                  + f" (smallest heyoka/varint cost ratio over each method's errors ≥ 1e-8); "
                    f"load {result['precision']['load'][0]:.1f}, "
                    f"{result['precision'].get('clock', 'wall')} time",
                  holds=worst[best_label] >= 0.5,
                  note=("" if worst[best_label] >= 0.5 else
                        "heyoka's high-order Taylor steps are far longer than an implicit "
                        "Runge–Kutta step of equal accuracy on these smooth, small systems")
                  + ("" if result["precision"].get("warmed") else
                     " Measured before every tolerance was warmed up: heyoka's times at "
                     "tolerances after its first include building its integrator, so only "
                     "its loosest point is clean."))
    c.save()


def main(argv=None):
    def extra(parser):
        parser.add_argument("--part", default=",".join(PARTS),
                            help=f"parts to run, comma-separated, of {', '.join(PARTS)}")
        parser.add_argument("--repeats", type=int, default=REPEATS)
        parser.add_argument("--galpy-rtols", default=",".join(map(str, GALPY_RTOLS)),
                            help="galpy's rtols in the bar part, comma-separated (minutes each)")
        parser.add_argument("--precision-clock", choices=("wall", "cpu"), default="cpu",
                            help="the precision part's clock: the process's CPU time (every "
                                 "contender one thread; the default on a loaded machine) or "
                                 "wall time")
        parser.add_argument("--systems", default="",
                            help="the precision part's systems whose names contain one of "
                                 "these strings, comma-separated (default: all)")
        parser.add_argument("--maps-clock", choices=("wall", "cpu"), default="wall",
                            help="the maps part's clock: wall time, or the process's CPU time "
                                 "(every contender one thread; on a loaded machine)")
        parser.add_argument("--bar-clock", choices=("wall", "cpu"), default="wall",
                            help="the bar part's clock: wall time, or the process's CPU time "
                                 "(every contender one thread; on a loaded machine)")
        parser.add_argument("--galpy-stored", default=None, metavar="JSON",
                            help="the bar part takes galpy's rows from this stored "
                                 "hamiltonians_bar.json instead of running galpy (minutes "
                                 "per call); each row names the run it comes from")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    parts = [p.strip() for p in args.part.split(",") if p.strip()]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        raise SystemExit(f"unknown part {unknown[0]!r}; expected some of {', '.join(PARTS)}")
    result = {"quick": args.quick}
    if "published" in parts:
        rows = published_case(args.quick)
        save_csv(args.out, "hamiltonians_published", rows,
                 ["quantity", "published", "ours", "difference", "source"])
        result["published"] = {"rows": rows}
        for r in rows:
            print(f"{r['quantity']}: published {r['published']}, ours {r['ours']:.6g}")
    if "maps" in parts:
        start = load()
        clock = time.process_time if args.maps_clock == "cpu" else time.perf_counter
        rows, summary = maps_case(args.quick, args.repeats, clock)
        save_csv(args.out, "hamiltonians_maps", rows,
                 ["indicator", "contender", "config", "seconds", "agreement", "orbits", "t_end"])
        result["maps"] = {"rows": rows, "summary": summary, "load": start, "load_end": load(),
                          "clock": args.maps_clock}
    if "bar" in parts:
        start = load()
        rtols = tuple(float(v) for v in args.galpy_rtols.split(",") if v.strip())
        clock = time.process_time if args.bar_clock == "cpu" else time.perf_counter
        rows = bar_case(args.quick, args.repeats, rtols, clock, args.galpy_stored)
        save_csv(args.out, "hamiltonians_bar", rows,
                 ["orbit", "contender", "seconds", "x1", "x1_reference", "error", "t_end"])
        result["bar"] = {"rows": rows, "load": start, "load_end": load(), "galpy_rtols": rtols,
                         "clock": args.bar_clock, "galpy_stored": args.galpy_stored}
    if "precision" in parts:
        start = load()
        clock = time.process_time if args.precision_clock == "cpu" else time.perf_counter
        only = tuple(v.strip() for v in args.systems.split(",") if v.strip())
        rows, summary = precision_case(args.quick, args.repeats, clock=clock, only=only)
        save_csv(args.out, "hamiltonians_precision", rows,
                 ["system", "contender", "knob", "seconds", "error", "t_end"])
        result["precision"] = {"rows": rows, "summary": summary, "load": start,
                               "load_end": load(), "warmed": "every knob",
                               "clock": args.precision_clock}
    for part in parts:
        save_json(args.out, f"hamiltonians_{part}", {"quick": args.quick, part: result[part]})
    # The claims of every part run so far into this directory (parts may be
    # run one at a time).
    every = {}
    for part in PARTS:
        path = Path(args.out) / f"hamiltonians_{part}.json"
        if path.exists():
            every[part] = json.loads(path.read_text())[part]
    claims(args.out, every)
    return result


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
