"""The two-particle method, measured: where it goes wrong against the TM
method and the Taylor reference.

Skokos & Gerlach (2010) leave the two-particle method out as "less
efficient and reliable" than integrating the variational equations
(Benettin et al. 1976; Contopoulos et al. 1978). varint has it as a method
(``method="two-particle"``: a neighbour at distance d0 along each
deviation vector, advanced by the same splitting scheme as the orbit, put
back at d0 every τ), so the claim can be measured:

1. X1 error against the extended-precision Taylor reference, as a function
   of d0 and τ, on R1 (regular), C1 (chaotic, to t = 300, within the
   reference's validity, see studies/accuracy.py) and R3 (FPU-β, N = 8),
   beside the TM method's error at the same τ. The reference orbit of the
   two-particle run is the TM method's orbit, bit for bit (the same
   stepper), so the difference between the two errors is the method's own.
   Expected: an error ∝ d0 from the curvature of the flow over the
   separation, one ∝ 1/d0 from rounding the separation (a difference of
   two numbers of size |x|), a best d0 near √ε.
2. In time, on R1: the error is a bias that does not decay, so the
   two-particle X1 of a regular orbit leaves the law (ln t + c)/t once X1
   falls to the bias.
3. GALI on R1: on a 2-torus GALI_3 and GALI_4 fall as t⁻² and t⁻⁴ (paper
   eq. 17); the two-particle method's vectors carry the rounding of the
   separations (≈ ε|x|/d0 relative, every interval), so its GALIs leave
   those laws decades before the TM method's round-off floor (t ≈ 1e7,
   studies/roundoff_floor.py).
4. Cost at equal accuracy: the cheapest τ and scheme that reach a target
   X1 error, per method, by CPU time (minimum of interleaved repeats) and
   by force evaluations. CPU time, not wall time: on a shared machine a run
   longer than a time slice is preempted, and its wall time measured
   5-6× its CPU time (load average 9 on 2 cores) whatever the repeats.

Usage: ``python studies/two_particle.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies import claims as rules  # noqa: E402
from studies.common import Claims, figure, parse_args, save_csv, save_json  # noqa: E402
from studies.laws import slope  # noqa: E402
from varint.cache import reference  # noqa: E402

ORBITS = ("R1", "C1", "R3")
#: Horizons of the error tables (full, quick); C1 within the reference's
#: validity (t ≤ 500, studies/accuracy.py).
T_END = ({"R1": 1000.0, "C1": 300.0, "R3": 1000.0}, {"R1": 100.0, "C1": 100.0, "R3": 50.0})
#: Initial separations (full, quick).
D0S = (tuple(10.0 ** -j for j in range(2, 14)), (1e-3, 1e-4, 1e-5, 1e-8, 1e-11, 1e-12, 1e-13))
#: Renormalisation intervals = steps, on the reference grid 0.1·2^j (full, quick).
TAUS = ((0.2, 0.1, 0.05, 0.025), (0.1, 0.05))
SCHEME = "SBAB2C"
#: Windows of d0 over which the error laws are fitted: curvature (∝ d0)
#: and rounding (∝ 1/d0).
CURVATURE_D0 = (1e-7, 1e-3)
ROUNDING_D0 = (1e-13, 1e-10)
#: Part 2: R1 in time (full, quick) and the separations shown.
T_TIME = (1e6, 2e3)
D0_TIME = (1e-3, 1e-5, 1e-8)
#: Part 3: GALIs of R1 (full, quick horizons).
T_GALI = (1e5, 3e3)
#: Part 4: targets of the X1 error and the configurations scanned.
TARGETS = (1e-6, 1e-8)
COST_TAUS = ((0.4, 0.2, 0.1, 0.05, 0.025, 0.0125), (0.1, 0.05))
COST_SCHEMES = ("SBAB2C", "ABA864")
REPEATS = (3, 1)
BEST_D0 = 1e-8


def _x1(model, x0, T, tau, method="tm", **opts):
    return varint.run(model, x0, "x1", T, tau=tau, method=method, t_out=[T], progress=False,
                      **opts)


def _forces(counts):
    """Force evaluations: gradients, plus Hessians and third-derivative
    contractions counted as one force each (the same order of cost for
    these potentials)."""
    return sum(int(counts.get(k, 0)) for k in ("gradient", "hessian", "third"))


def error_tables(quick):
    """Part 1: |X1 − X1_ref| at t_end for the TM method and the
    two-particle method for every (d0, τ), per orbit."""
    q = int(quick)
    rows = []
    for name in ORBITS:
        model, x0 = varint.paper_orbit(name)
        T = T_END[q][name]
        ref = reference(model, x0, T, tau=0.1, kind="lyapunov_spectrum", n_exponents=1,
                        t_out=[T]).exponents[-1, 0]
        for tau in TAUS[q]:
            r = _x1(model, x0, T, tau, scheme=SCHEME)
            rows.append({"orbit": name, "tau": tau, "method": "tm", "d0": float("nan"),
                         "X1": r.exponents[-1, 0], "X1_ref": ref,
                         "error": abs(r.exponents[-1, 0] - ref)})
            for d0 in D0S[q]:
                r = _x1(model, x0, T, tau, "two-particle", scheme=SCHEME, d0=d0)
                rows.append({"orbit": name, "tau": tau, "method": "two-particle", "d0": d0,
                             "X1": r.exponents[-1, 0], "X1_ref": ref,
                             "error": abs(r.exponents[-1, 0] - ref)})
    return rows


def _error_laws(rows, name, tau):
    """Slopes of log error against log d0 in the curvature and rounding
    windows, the best d0 and its error, and the TM error at this τ."""
    tp = [r for r in rows if r["orbit"] == name and r["tau"] == tau
          and r["method"] == "two-particle"]
    tm = next(r for r in rows if r["orbit"] == name and r["tau"] == tau and r["method"] == "tm")
    d0 = np.array([r["d0"] for r in tp])
    # The method's own error: the part the TM method (same orbit) does not have.
    own = np.array([abs(r["X1"] - tm["X1"]) for r in tp])
    err = np.array([r["error"] for r in tp])
    best = int(np.argmin(own))
    return {"curvature_slope": slope(d0, own, *CURVATURE_D0),
            "rounding_slope": slope(d0, own, *ROUNDING_D0),
            "best_d0": float(d0[best]), "best_own": float(own[best]),
            "best_error": float(err[best]), "tm_error": tm["error"], "d0": d0, "own": own}


def in_time(quick):
    """Part 2: X1(t) of R1 by the TM method and the two-particle method;
    the error's level over the last decade and when it first reaches 10 %
    of X1."""
    model, x0 = varint.paper_orbit("R1")
    T = T_TIME[int(quick)]
    tm = varint.run(model, x0, "x1", T, tau=0.05, progress=False)
    out = {"t": tm.t, "tm": tm.exponents[:, 0], "two_particle": {}}
    for d0 in D0_TIME:
        r = varint.run(model, x0, "x1", T, tau=0.05, method="two-particle", d0=d0,
                       progress=False)
        x = r.exponents[:, 0]
        bias = x - out["tm"]
        late = tm.t >= T / 10
        wrong = np.flatnonzero((tm.t >= 10) & (np.abs(bias) > 0.1 * np.abs(out["tm"])))
        out["two_particle"][d0] = {"X1": x, "bias_level": float(np.median(bias[late])),
                                   "t_10pct": float(tm.t[wrong[0]]) if wrong.size else None}
    return out


def gali_floors(quick):
    """Part 3: the GALIs of R1 by both methods, and where the two-particle
    method's leave the TM method's (a decade apart, to the end of the run:
    rule ``departure``)."""
    model, x0 = varint.paper_orbit("R1")
    T = T_GALI[int(quick)]
    out = {}
    for method, opts in (("tm", {}), ("two-particle", {"d0": BEST_D0})):
        out[method] = {"series": varint.gali(model, x0, T, tau=0.05, k=(2, 3, 4),
                                             method=method, progress=False, **opts)}
    tm, tp = out["tm"]["series"], out["two-particle"]["series"]
    for k in (2, 3, 4):
        excess = np.abs(np.log(tp.gali[k] / tm.gali[k]))
        out["two-particle"][k] = rules.departure(tm.t, excess, f"GALI_{k}: ")
        out["tm"][k] = float(tm.gali[k][-1])
        out["two-particle"][f"last_{k}"] = float(tp.gali[k][-1])
    return out


def cost_at_equal_accuracy(quick):
    """Part 4: every (method, scheme, τ) of the scan on R1 and C1: X1 error,
    force evaluations and CPU time per unit time (minimum over interleaved
    repeats); then, per target, each method's cheapest configuration that
    reaches it."""
    q = int(quick)
    rows = []
    for name in ("R1", "C1"):
        model, x0 = varint.paper_orbit(name)
        T = T_END[q][name]
        ref = reference(model, x0, T, tau=0.1, kind="lyapunov_spectrum", n_exponents=1,
                        t_out=[T]).exponents[-1, 0]
        configs = [(m, s, tau) for s in COST_SCHEMES for tau in COST_TAUS[q]
                   for m in ("tm", "two-particle")]
        for m, s, tau in configs:  # compile outside the clock
            _x1(model, x0, 10 * tau, tau, m, scheme=s)
        seconds = {c: math.inf for c in configs}
        results = {}
        for _ in range(REPEATS[q]):
            for c in configs:  # interleaved: the machine's load hits every one alike
                m, s, tau = c
                opts = {"d0": BEST_D0} if m == "two-particle" else {}
                t0 = time.process_time()
                results[c] = _x1(model, x0, T, tau, m, scheme=s, **opts)
                seconds[c] = min(seconds[c], time.process_time() - t0)
        for (m, s, tau), r in results.items():
            rows.append({"orbit": name, "method": m, "scheme": s, "tau": tau,
                         "error": abs(r.exponents[-1, 0] - ref),
                         "forces_per_time": _forces(r.provenance.counts) / T,
                         "cpu_seconds_per_time": seconds[(m, s, tau)] / T})
    best = []
    for name in ("R1", "C1"):
        for target in TARGETS:
            entry = {"orbit": name, "target": target}
            for m in ("tm", "two-particle"):
                ok = [r for r in rows if r["orbit"] == name and r["method"] == m
                      and r["error"] <= target]
                if ok:
                    c = min(ok, key=lambda r: r["cpu_seconds_per_time"])
                    entry[m] = {k: c[k] for k in ("scheme", "tau", "error", "forces_per_time",
                                                  "cpu_seconds_per_time")}
                else:
                    entry[m] = None
            best.append(entry)
    return rows, best


def _plot(out, rows, laws_by, time_part, floors):
    path, plt = figure(out, "two_particle")
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), layout="constrained")
    ax = axes[0]
    for name in ORBITS:
        tau = min(r["tau"] for r in rows if r["orbit"] == name)
        tp = [r for r in rows if r["orbit"] == name and r["tau"] == tau
              and r["method"] == "two-particle"]
        tm = next(r for r in rows if r["orbit"] == name and r["tau"] == tau
                  and r["method"] == "tm")
        line, = ax.loglog([r["d0"] for r in tp], [r["error"] for r in tp], "o-",
                          label=f"{name}, τ = {tau:g}")
        ax.axhline(tm["error"], color=line.get_color(), ls=":", lw=1)
    ax.set_xlabel("d0")
    ax.set_ylabel("|X1 − X1_ref| at t_end")
    ax.set_title("two-particle (dots: TM at the same τ)")
    ax.legend(fontsize=8)
    ax = axes[1]
    t = time_part["t"]
    ax.loglog(t, np.abs(time_part["tm"]), "k", label="TM")
    for d0, v in time_part["two_particle"].items():
        ax.loglog(t, np.abs(v["X1"]), label=f"two-particle d0 = {d0:g}")
    ax.set_xlabel("t")
    ax.set_ylabel("|X1|")
    ax.set_title("R1: X1 in time")
    ax.legend(fontsize=8)
    ax = axes[2]
    for method, style in (("tm", "-"), ("two-particle", "--")):
        g = floors[method]["series"]
        for k in (2, 3, 4):
            ax.loglog(g.t, g.gali[k], style, label=f"{method} GALI_{k}")
    ax.set_xlabel("t")
    ax.set_ylabel("GALI_k")
    ax.set_title(f"R1: GALIs (two-particle d0 = {BEST_D0:g})")
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    quick, out = args.quick, args.out
    t_start = time.perf_counter()
    rows = error_tables(quick)
    save_csv(out, "two_particle_error", rows, ["orbit", "tau", "method", "d0", "X1", "X1_ref",
                                               "error"])
    laws_by = {(name, tau): _error_laws(rows, name, tau)
               for name in ORBITS for tau in TAUS[int(quick)]}
    time_part = in_time(quick)
    floors = gali_floors(quick)
    cost_rows, best = cost_at_equal_accuracy(quick)
    save_csv(out, "two_particle_cost", cost_rows, ["orbit", "method", "scheme", "tau", "error",
                                                   "forces_per_time", "cpu_seconds_per_time"])
    fig = _plot(out, rows, laws_by, time_part, floors)
    claims = Claims("two_particle", out, source="own")
    _claims(claims, laws_by, time_part, floors, best, quick, fig)
    claims.save()
    summary = {
        "error_laws": {f"{n} tau={tau:g}": {k: v for k, v in law.items() if k not in ("d0", "own")}
                       for (n, tau), law in laws_by.items()},
        "in_time": {f"{d0:g}": {k: v for k, v in part.items() if k != "X1"}
                    for d0, part in time_part["two_particle"].items()},
        "gali": {"tm_last": {k: floors["tm"][k] for k in (2, 3, 4)},
                 "two_particle_last": {k: floors["two-particle"][f"last_{k}"]
                                       for k in (2, 3, 4)},
                 "two_particle_departs": {k: floors["two-particle"][k].value
                                          for k in (2, 3, 4)}},
        "cost": best, "seconds": time.perf_counter() - t_start}
    save_json(out, "two_particle", summary)
    _print(rows, laws_by, time_part, floors, best)
    return {"rows": rows, "laws": laws_by, "time": time_part, "floors": floors,
            "cost": best, "claims": claims.items}


def _claims(claims, laws_by, time_part, floors, best, quick, fig):
    taus = TAUS[int(quick)]
    tau = min(taus)
    # The paper's claim, in two parts: less reliable, less efficient.
    for name in ORBITS:
        law = laws_by[(name, tau)]
        j = rules.above(law["best_own"], law["tm_error"],
                        f"{name}, τ = {tau:g}: the method's own X1 error at its best d0 "
                        f"({law['best_d0']:g}) {law['best_own']:.2g} vs TM's whole error "
                        f"{law['tm_error']:.2g}, ")
        claims.add(f"{name}: the two-particle method adds an X1 error larger than the "
                   "variational equations' (TM) whole error, even at its best d0",
                   "less reliable (Sect. VII)", j.text, j.holds, fig, rules=[j],
                   source="paper", note=_reliability_note(j))
    for entry in best:
        tm, tp = entry["tm"], entry["two-particle"]
        what = f"{entry['orbit']}, X1 error ≤ {entry['target']:g}: "
        if tm is None:
            claims.add(f"{what}cost at equal accuracy", "less efficient (Sect. VII)",
                       "TM does not reach the target in the scan", None, source="paper")
            continue
        if tp is None:
            claims.add(f"{what}the two-particle method costs more at equal accuracy",
                       "less efficient (Sect. VII)",
                       f"two-particle never reaches it (TM: {tm['scheme']}, τ = {tm['tau']:g})",
                       True, source="paper")
            continue
        j = rules.costs_more(tp["cpu_seconds_per_time"], tm["cpu_seconds_per_time"], what)
        claims.add(f"{what}the two-particle method costs more at equal accuracy",
                   "less efficient (Sect. VII)",
                   j.text + f" (TM {tm['scheme']} τ = {tm['tau']:g}; two-particle "
                   f"{tp['scheme']} τ = {tp['tau']:g}; forces per unit time "
                   f"{tp['forces_per_time']:.3g} vs {tm['forces_per_time']:.3g}, two-particle "
                   "vs TM)",
                   j.holds, rules=[j], source="paper",
                   note="" if j.holds is not False else "measured cheaper at this target")
    # varint's own checks of why.
    for name in ORBITS:
        law = laws_by[(name, tau)]
        d0, own = law["d0"], law["own"]
        j = rules.power_law(d0, own, 1.0, CURVATURE_D0)
        claims.add(f"{name}: the two-particle error from the curvature of the flow grows as d0",
                   "", j.text.replace("t =", "d0 ="), j.holds, fig, rules=[j])
        j = rules.power_law(d0, own, -1.0, ROUNDING_D0)
        claims.add(f"{name}: its rounding error grows as 1/d0", "",
                   j.text.replace("t =", "d0 ="), j.holds, fig, rules=[j],
                   note="" if j.holds is not False else "rounding of the separations is not "
                   "a random walk of one size; the slope is steeper where the error nears X1")
        claims.add(f"{name}: the best d0 is near √ε ≈ 1.5e-8", "",
                   f"best d0 = {law['best_d0']:g} (own error {law['best_own']:.2g}; error "
                   f"against the reference {law['best_error']:.2g})", None)
    for d0, part in time_part["two_particle"].items():
        wrong = part["t_10pct"]
        claims.add(f"R1, d0 = {d0:g}: the two-particle X1 carries a bias that does not decay; "
                   "it is wrong by 10 % once X1 falls to it", "",
                   f"bias over the last decade {part['bias_level']:.2g}; 10 % wrong from "
                   + ("— (not within the run)" if wrong is None else f"t ≈ {wrong:.2g}"),
                   None, fig)
    for k in (3, 4):
        j = floors["two-particle"][k]
        claims.add(f"R1: GALI_{k} of the two-particle method (d0 = {BEST_D0:g}) leaves the "
                   f"t^-{2 * (k - 2)} law of the TM method's (whose own round-off floor comes "
                   "from t ≈ 1e7)", "",
                   j.text + f"; at t_end {floors['two-particle'][f'last_{k}']:.2g} vs TM "
                   f"{floors['tm'][k]:.2g}", j.holds, fig, rules=[j],
                   note="" if j.holds else "not within this run's horizon")


def _reliability_note(j):
    """Why the method's own error did not come out above TM's whole error."""
    if j.holds is not False:
        return ""
    if j.value < 1:
        return ("the integration error both methods share is the larger (on a chaotic orbit "
                "it grows as e^{λt})")
    return f"larger by {j.value:.2g}×, not by the rule's factor {rules.ABOVE_FACTOR:g}"


def _print(rows, laws_by, time_part, floors, best):
    print("X1 error against the Taylor reference at t_end (SBAB2C)")
    for (name, tau), law in laws_by.items():
        cells = "  ".join(f"{d:.0e}:{e:.1e}" for d, e in zip(
            law["d0"], [r["error"] for r in rows if r["orbit"] == name and r["tau"] == tau
                        and r["method"] == "two-particle"], strict=False))
        print(f"{name} tau={tau:<6g} TM {law['tm_error']:.1e} | two-particle {cells}")
        print(f"{'':12} slope vs d0: curvature {law['curvature_slope']:.2f}, rounding "
              f"{law['rounding_slope']:.2f}; best d0 {law['best_d0']:g} (own error "
              f"{law['best_own']:.1e})")
    print("R1 in time (tau = 0.05): bias of two-particle X1 over the last decade")
    for d0, part in time_part["two_particle"].items():
        print(f"  d0 = {d0:g}: bias {part['bias_level']:.2g}, 10 % wrong from t = "
              f"{part['t_10pct']}")
    print("R1 GALI_k at t_end (TM / two-particle) and where two-particle departs:",
          {k: f"{floors['tm'][k]:.1e} / {floors['two-particle'][f'last_{k}']:.1e}, "
              f"{floors['two-particle'][k].text}" for k in (2, 3, 4)})
    print("Cost at equal accuracy (CPU time per unit time, forces per unit time)")
    for e in best:
        cells = []
        for m in ("tm", "two-particle"):
            c = e[m]
            cells.append(f"{m}: " + ("not reached" if c is None else
                                     f"{c['scheme']} tau={c['tau']:g} err={c['error']:.1e} "
                                     f"{c['cpu_seconds_per_time'] * 1e3:.3g} ms "
                                     f"{c['forces_per_time']:.3g} forces"))
        print(f"  {e['orbit']} target {e['target']:g}: " + " | ".join(cells))


if __name__ == "__main__":
    main()
