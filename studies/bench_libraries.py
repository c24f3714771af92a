"""Each baseline against its own library driven directly, in one
interleaved run: no comparison of varint may be won against a handicapped
rival.

varint's three reference integrators wrap a library each
(:mod:`varint.baselines`): ``method="cvode"`` scikit-sundae's CVODE,
``method="taylor"`` heyoka, ``method="dop853"`` SciPy's DOP853 (compiled,
SciPy's arithmetic). Here each races its library used the way an expert
would use it on the same problem, at the same tolerance:

Problem: the Lyapunov spectrum of R1 (regular) and C1 (chaotic) with QR
every τ = 0.05, from the same k = 1 or 4 seeded deviation vectors, to
t = 1000 (R1) and 100 (C1; 100 and 20 with ``--quick``): the final orbit
and exponents.

* **scikit-sundae directly**: ``CVODE(rhs, method="Adams", rtol, atol)``
  with its defaults (dense linear solver, finite-difference Jacobian), one
  ``solve`` of orbit and vectors over the whole span on the τ grid — no
  restart — on varint's compiled right-hand side (:mod:`varint.baselines.rhs`:
  the library is given the same function, so only the driving differs);
  both at rtol = atol = 1e-8, 1e-10 (varint's default) and 1e-12 (varint
  also at 1e-13).
* **heyoka directly**: ``taylor_adaptive(var_ode_sys(...))`` of the
  equations heyoka derives itself (k columns), one ``propagate_grid`` over
  the τ grid at its default tolerance.
* **SciPy directly**: ``solve_ivp(method="DOP853", rtol=atol=δ)``, one call
  over the whole span, at δ = 1e-5 (the paper's) and tighter, and SciPy's
  solver restarted every τ as the paper does (varint's
  ``engine="scipy"``, which drives ``scipy.integrate.DOP853`` itself).

The same problem means the same outputs: a run with QR every τ yields the
renormalised vectors and the exponents at every τ. A library used directly
gets them from its outputs on the τ grid by one QR of each raw output
(NumPy, all at once): log|R_ii(t_j)|/t_j are the exponents of QR every τ in
exact arithmetic (the R factors of a product telescope), valid while the
raw vectors stay finite and well conditioned, as they do over these spans
(rows "directly"). The rows "directly, final QR only" take the library's
shortcut when only the last exponents are wanted: one QR of the final
vectors. They are shown, not judged: they solve a smaller problem, and one
that fails on long chaotic runs (the raw vectors align and overflow).

Each time is the minimum over repeats taken in turn (a, b, c, a, b, c, …),
integration only (compilation and the construction of the integrator are
done before), in ms of CPU time (``time.process_time``: every contender
runs on one thread, and the machine is shared) per unit of integration
time. Errors are
against the extended-precision Taylor reference (cached): the orbit's
max |x − x_ref| at the end and the exponents' max |X_i − X_i,ref|.

A baseline *holds its own* against its library when it is not slower at
equal accuracy. CVODE's global error at one tolerance moves by factors with
where its steps and restarts fall (one solve at 1e-10 on R1: 3.9e-8 with
SUNDIALS' difference Jacobian, 1.4e-7 with the exact one), so there each
point of scikit-sundae's is compared with varint's cost–error front, read
at the same orbit error (:func:`claims.as_cheap_at_equal_error`). The
exponents' errors are shown beside it, not judged: with one vector X1's
error is a signed number that can all but vanish by cancellation (R1, one
solve at 1e-12: 2.2e-14 against an orbit error of 1.5e-9). heyoka's and DOP853's errors are at round-off or far
below SciPy's: there varint's one setting must be as fast and as accurate
as each of the library's (:func:`claims.dominates`).

Usage: ``python studies/bench_libraries.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.claims import as_cheap_at_equal_error, dominates, pareto  # noqa: E402
from studies.common import (STARTED, Claims, interleaved, parse_args,  # noqa: E402
                            save_csv, save_json)
from varint.cache import reference  # noqa: E402
from varint.methods import make_propagator  # noqa: E402
from varint.state import RunState, initial_deviations  # noqa: E402

TAU = 0.05
#: CVODE's tolerances (rtol = atol): varint's default 1e-10 and around it
#: (varint's front one tolerance further, so that it can be read at the
#: errors of all of scikit-sundae's points).
CVODE_TOLS = (1e-8, 1e-10, 1e-12)
CVODE_FRONT = (*CVODE_TOLS, 1e-13)
#: SciPy's DOP853 driven directly over the whole span at these δ.
SCIPY_DELTAS = (1e-5, 1e-8, 1e-11, 1e-13)


def _final_qr(ys, d, k, t_end):
    """Orbit and exponents from the flat states (x, raw W) on the τ grid:
    one QR of the final vectors, log|R_ii|/t."""
    R = np.linalg.qr(ys[-1, d:].reshape(d, k), mode="r")
    return ys[-1, :d].copy(), np.log(np.abs(np.diag(R))) / t_end


def _every_qr(ys, d, k, t_end):
    """The same from one QR of every output after t = 0 (all at once): the
    exponents at every τ, of which the last is returned."""
    W = ys[1:, d:].reshape(len(ys) - 1, d, k)
    R = np.linalg.qr(W, mode="r")
    t = TAU * np.arange(1, len(ys))
    X = np.log(np.abs(np.diagonal(R, axis1=1, axis2=2))) / t[:, None]
    return ys[-1, :d].copy(), X[-1]


def contenders(model, x0, W0, t_end, quick):
    """label -> (library, callable returning (orbit, exponents)), every
    integrator built and warmed up."""
    import heyoka as hy
    from scipy.integrate import solve_ivp
    from sksundae.cvode import CVODE

    from varint.baselines.rhs import tangent_rhs
    from varint.baselines.taylor import heyoka_system

    d, k = W0.shape
    n = int(round(t_end / TAU))
    grid = TAU * np.arange(n + 1)
    y0 = np.concatenate([x0, W0.ravel()])
    rhs, fun = tangent_rhs(model)

    def varint_run(method, **options):
        prop = make_propagator(method, model, TAU, "qr", **options)
        prop.advance(RunState.start(x0[None], W0[None]), 1)
        if hasattr(prop, "set_horizon"):
            prop.set_horizon(n)  # as a run to t_end does

        def go():
            state = RunState.start(x0[None], W0[None])
            prop.advance(state, n)
            return state.x[0].copy(), state.renormalized("qr").log_growth()[0] / t_end
        return go

    sundae = {tol: CVODE(rhs, method="Adams", rtol=tol, atol=tol, max_num_steps=100_000)
              for tol in CVODE_TOLS}
    system, variables = heyoka_system(model.symbolic())
    ta = hy.taylor_adaptive(hy.var_ode_sys(system, variables[:k], order=1),
                            np.zeros(d * (1 + k)))

    def heyoka_states():
        ta.time = 0.0
        ta.state[:] = y0
        return ta.propagate_grid(grid)[-1]

    def scipy_states(delta):
        return lambda: solve_ivp(fun, (0.0, t_end), y0, method="DOP853", rtol=delta,
                                 atol=delta, t_eval=grid).y.T

    def directly(states, qr):
        return lambda: qr(states(), d, k, t_end)

    library = {f"scikit-sundae tol={tol:g}": (lambda s=s: s.solve(grid, y0).y)
               for tol, s in sundae.items()}
    library["heyoka"] = heyoka_states
    library.update({f"SciPy δ={delta:g}": scipy_states(delta) for delta in SCIPY_DELTAS})
    tasks = {f"cvode (varint) tol={tol:g}": ("scikit-sundae", "varint",
                                             varint_run("cvode", rtol=tol, atol=tol))
             for tol in CVODE_FRONT}
    tasks.update({"taylor (varint)": ("heyoka", "varint", varint_run("taylor")),
             "dop853 (varint) δ=1e-5": ("SciPy", "varint", varint_run("dop853", delta=1e-5))})
    for name, states in library.items():
        lib = name.split(" ")[0]
        tasks[f"{name} directly"] = (lib, "directly", directly(states, _every_qr))
        tasks[f"{name} directly, final QR only"] = (lib, "final QR only",
                                                    directly(states, _final_qr))
    if not quick:
        # SciPy's own solver restarted every τ (Python at every step): slow.
        tasks["SciPy restarted every τ δ=1e-5"] = (
            "SciPy", "directly", varint_run("dop853", delta=1e-5, engine="scipy"))
    for _, _, task in tasks.values():
        task()
    return tasks


def race(orbit, t_end, ks, repeats, quick):
    """The rows of one orbit: every contender, k = each of ``ks``."""
    model, x0 = varint.paper_orbit(orbit)
    rows = []
    for k in ks:
        W0 = initial_deviations(model.dim, k, 1, seed=0)[0]
        ref = reference(model, x0, t_end, TAU, kind="lyapunov_spectrum", deviations=W0,
                        t_out=1)
        tasks = contenders(model, x0, W0, t_end, quick)
        best, out = interleaved({label: task for label, (_, _, task) in tasks.items()},
                                repeats, clock=time.process_time)
        for label, (library, kind, _) in tasks.items():
            x, X = out[label]
            rows.append({"orbit": orbit, "k": k, "library": library, "kind": kind,
                         "contender": label,
                         "ms_per_tu": 1e3 * best[label] / t_end,
                         "orbit_error": float(np.abs(x - ref.state).max()),
                         "X_error": float(np.abs(X - ref.exponents[-1]).max())})
    return rows


def add_claims(claims, rows):
    """One claim per baseline, orbit and k: it holds its own against its
    library driven directly for the same outputs — CVODE at equal error on
    the cost–error fronts of its tolerances
    (:func:`claims.as_cheap_at_equal_error`, orbit and exponent errors),
    heyoka and DOP853 at their one setting (:func:`claims.dominates`); the
    shortcut of a final QR only is quoted beside it."""
    for orbit, k in sorted({(r["orbit"], r["k"]) for r in rows}):
        here = [r for r in rows if (r["orbit"], r["k"]) == (orbit, k)]
        for lib in dict.fromkeys(r["library"] for r in here):
            mine = [r for r in here if r["library"] == lib and r["kind"] == "varint"]
            rivals = [r for r in here if r["library"] == lib and r["kind"] == "directly"]
            short = [r for r in here if r["library"] == lib and r["kind"] == "final QR only"]
            if len(mine) > 1:
                front = pareto([(r["ms_per_tu"], r["orbit_error"]) for r in mine])
                js = [as_cheap_at_equal_error(front, r["ms_per_tu"], r["orbit_error"],
                                              f"{r['contender']}: ") for r in rivals]
                ours = f"{mine[0]['contender'].split(' tol=')[0]} (tolerances " + ", ".join(
                    r["contender"].split("tol=")[1] for r in mine) + ")"
                text = "; ".join(j.text for j in js) + "; exponent errors, varint " + ", ".join(
                    f"{r['X_error']:.1e}" for r in mine) + ", directly " + ", ".join(
                    f"{r['X_error']:.1e}" for r in rivals)
            else:
                m = mine[0]
                js = [dominates(m["ms_per_tu"], m["orbit_error"], r["ms_per_tu"],
                                r["orbit_error"], f"{r['contender']}: ") for r in rivals]
                ours = m["contender"]
                text = (f"{m['ms_per_tu']:.3g} ms/tu, orbit error {m['orbit_error']:.1e}; "
                        + "; ".join(j.text for j in js))
            claims.add(f"{orbit}, k = {k}: {ours} is as fast and as accurate as {lib} driven "
                       "directly for the same outputs", "-", text, all(j.holds for j in js),
                       rules=js, note="with a final QR only (no exponents along the run): "
                       + "; ".join(f"{r['contender']} {r['ms_per_tu']:.3g} ms/tu" for r in short))


def main(argv=None):
    def extra(parser):
        parser.add_argument("--judge-stored", action="store_true",
                            help="judge the claims again from the stored measurements")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    if args.judge_stored:
        stored = json.loads((args.out / "bench_libraries.json").read_text())
        claims = Claims("bench_libraries", args.out, source="own")
        add_claims(claims, stored["rows"])
        claims.save()
        save_json(args.out, "bench_libraries", {**stored, "claims": claims.items},
                  judged_again=True)
        return stored
    horizons = {"R1": 100.0, "C1": 20.0} if args.quick else {"R1": 1000.0, "C1": 100.0}
    rows = []
    for orbit, t_end in horizons.items():
        rows += race(orbit, t_end, (1, 4), 1 if args.quick else 5, args.quick)
    print(f"\nEach baseline against its library, τ = {TAU}, QR every τ (min of interleaved "
          f"repeats; load {STARTED['load']} at the start)")
    for r in rows:
        print(f"{r['orbit']} k={r['k']} {r['contender']:<40} {r['ms_per_tu']:9.4f} ms/tu  "
              f"orbit {r['orbit_error']:.1e}  X {r['X_error']:.1e}")
    claims = Claims("bench_libraries", args.out, source="own")
    add_claims(claims, rows)
    claims.save()
    save_csv(args.out, "bench_libraries", rows, list(rows[0]))
    result = {"horizons": horizons, "tau": TAU, "rows": rows, "claims": claims.items}
    save_json(args.out, "bench_libraries", result)
    return result


if __name__ == "__main__":
    main()
