"""Many-body lattices: which scheme is cheapest at a given energy error
(Danieli, Many Manda, Mithun & Skokos 2019, "D19"), and the chaos laws of
disordered lattices at the horizons this machine allows.

Part (a), efficiency. One deviation vector with the orbit (the mLCE
setting of D19), every scheme at a ladder of step sizes and the reference
integrators at a ladder of tolerances; per run the largest relative energy
error over the output times and the wall time (the minimum of repeats,
compilation excluded by a warm-up run). From each ladder the time needed
for a target error (1e-5 and 1e-8, D19's "moderate" and "high" accuracy)
is interpolated on log–log axes. Cases:

* ``fput``: FPUT chain, fixed ends, α = 0.25, β = 1, momenta on a central
  block (energy density 0.1): ABA864, SRKN14a, SABA2C, s11odr6 against
  DOP853 and heyoka's Taylor method (``var_ode_sys``).
* ``kg``: disordered Klein–Gordon chain, W = 4, a central block of energy
  density 0.1: the same schemes and baselines.
* ``ddnls``: 1D DDNLS, W = 4, β = 1, a central block of 21 sites of norm
  density 1: the three-part compositions ABC2 … s21ABC8 and two two-part
  schemes (ABA864, s11odr6 over the on-site | hopping split). The
  reference integrators need band Hessians, which the DDNLS (H not
  T(p) + V(q)) has not: no baseline here.
* ``ddnls2d``: the same on a square lattice (W = 10).

D19's parameters (sizes, horizons, energies) could not be read (only the
paper's abstract was reachable): every parameter here is ours.

Part (b), chaos laws. Ensembles over disorder (``varint.ensemble``, one
deviation vector, indicator ``"dvd"``) of single-site or block
excitations, with the disorder-averaged exponents of Λ(t) = X₁(t) and of
m₂(t) fitted over the last two decades, next to the papers' (abstracts of
Flach, Krimer & Skokos 2009; Laptyeva et al. 2010; Senyange, Many Manda &
Skokos 2018; Many Manda, Senyange & Skokos 2020). The papers integrate to
t = 1e9 and beyond with 50–100 realisations; the horizons and realisation
counts here are printed with every fit, and the parameters (W, E, β, L) are
ours — the papers' exact sets were not reachable. Realisations are kept in
``<out>/lattices_ensembles/`` and resumed.

Timings are wall times on a shared 2-core machine: only ratios within one
run mean anything. This is a benchmark and a measurement: it asserts
nothing.

Usage: ``python studies/lattices.py [--quick] [--out DIR] [--part efficiency|laws]``
(the two parts can run as two processes; each writes its own claims file)
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.claims import exponent_law  # noqa: E402
from studies.common import Claims, parse_args, save_csv, save_json  # noqa: E402
from varint.models import DDNLS, FPUT, DisorderedKG  # noqa: E402

TARGETS = (1e-5, 1e-8)
THREE_PART = ("ABC2", "ABC4_Y", "s9ABC6", "s11ABC6", "s17ABC8", "s21ABC8")
TWO_PART = ("ABA864", "SRKN14A", "SABA2C", "s11odr6")
#: The schemes D19 name as the most efficient (the paper's abstract).
D19_BEST = {"fput": {1e-5: {"ABA864"}, 1e-8: {"SRKN14A"}},
            "ddnls": {1e-5: {"s9ABC6", "s11ABC6"}, 1e-8: {"s17ABC8", "s19ABC8"}}}


# -- part (a): efficiency ------------------------------------------------------
def _cases(quick):
    n = 32 if quick else 256
    side = 6 if quick else 16
    t_end = 40.0 if quick else 100.0
    taus = (0.2, 0.1) if quick else (0.4, 0.2, 0.1, 0.05, 0.025)
    tols = (1e-6, 1e-10) if quick else (1e-5, 1e-7, 1e-9, 1e-11, 1e-13)
    fput = FPUT(n, 0.25, 1.0)
    kg = DisorderedKG(n, 4.0, 1)
    dd = DDNLS(n, 4.0, 1.0, 1)
    dd2 = DDNLS((side, side), 10.0, 1.0, 1)
    width = 5 if quick else 21
    baselines = [("DOP853", "dop853", "rtol", tol) for tol in tols]
    baselines += [("Taylor (heyoka)", "taylor", "tol", tol) for tol in tols]
    two = [(s, "tm", "scheme", tau) for s in TWO_PART for tau in taus]
    # The two-part split's linear flow is a dense O(N²) product (in the
    # Anderson eigenbasis): only the three largest steps.
    ddnls = [(s, "tm", "scheme", tau) for s in THREE_PART for tau in taus]
    ddnls += [(s, "tm", "scheme", tau) for s in ("ABA864", "s11odr6") for tau in taus[:3]]
    return [
        ("fput", fput, fput.initial_block(width, 0.1, seed=1), t_end, two + baselines),
        ("kg", kg, kg.initial_block(width, 0.1, seed=1), t_end, two + baselines),
        ("ddnls", dd, dd.initial_block(width, 1.0, seed=1), t_end, ddnls),
        ("ddnls2d", dd2, dd2.initial_block(3 if quick else 5, 1.0, seed=1), t_end / 2, ddnls),
    ]


def _one(model, x0, t_end, method, opts, tau, repeats):
    """(max relative energy error, wall seconds, X₁ at the end) of one
    configuration."""
    opts = dict(opts)
    if method == "taylor" and model.dim > 64:
        opts["compact_mode"] = True
    t_out = np.linspace(t_end / 20, t_end, 20)
    varint.run(model, x0, "x1", 2 * tau, tau, method=method, progress=False, **opts)
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = varint.run(model, x0, "x1", t_end, tau, method=method, t_out=t_out, seed=1,
                       progress=False, errors="flag", **opts)
        best = min(best, time.perf_counter() - t0)
        if best > 20 or r.status != 0:
            break
    if r.status != 0:       # unstable at this step (e.g. ABC4_Y at τ = 0.4 in 2D)
        return math.inf, best, math.nan
    err = float(np.max(np.abs(r.energy_error)))
    return err, best, float(r.exponents[-1, 0])


def time_at(errors, times, target):
    """Wall time at which a ladder reaches ``target`` energy error, by
    log–log interpolation between its two neighbouring runs (None outside
    the ladder)."""
    e, t = np.log(np.asarray(errors)), np.log(np.asarray(times))
    order = np.argsort(e)
    e, t = e[order], t[order]
    x = math.log(target)
    if not (e[0] <= x <= e[-1]) or len(e) < 2:
        return None
    return float(math.exp(np.interp(x, e, t)))


def efficiency(quick, out):
    rows, ranking = [], []
    repeats = 1 if quick else 2
    for case, model, x0, t_end, configs in _cases(quick):
        ladders = {}
        for label, method, key, value in configs:
            if method == "tm":
                opts, tau, setting = {"scheme": label}, value, f"τ={value:g}"
            else:
                # Renormalised every time unit (virtually: the integrators
                # keep their own steps between output times).
                opts, tau, setting = {key: value}, 1.0, f"{key}={value:g}"
            err, sec, x1 = _one(model, x0, t_end, method, opts, tau, repeats)
            rows.append({"case": case, "model": model.name, "sites": model.n_sites,
                         "t_end": t_end, "method": label, "setting": setting,
                         "energy_error": err, "seconds": sec, "x1": x1})
            if err > 0 and np.isfinite(err) and err < 1e-1:
                ladders.setdefault(label, []).append((err, sec))
            print(f"{case:8s} {label:16s} {setting:12s} err {err:9.2e}  {sec:8.3f} s  "
                  f"X1 {x1:.4g}", flush=True)
        for target in TARGETS:
            costs = {}
            for label, pts in ladders.items():
                errs, secs = zip(*pts, strict=True)
                sec = time_at(errs, secs, target) if len(pts) >= 2 else None
                if sec is not None:
                    costs[label] = (sec, False)
                elif max(errs) < target:
                    # Even its largest step beats the target: its cost there
                    # is at most that of its cheapest run.
                    costs[label] = (min(secs), True)
            if not costs:
                continue
            fastest = min(sec for sec, _ in costs.values())
            for label, (sec, bound) in sorted(costs.items(), key=lambda kv: kv[1][0]):
                ranking.append({"case": case, "target": target, "method": label,
                                "seconds": sec, "relative": sec / fastest,
                                "at_most": bound})
    save_csv(out, "lattices_efficiency", rows,
             ["case", "model", "sites", "t_end", "method", "setting", "energy_error",
              "seconds", "x1"])
    save_csv(out, "lattices_ranking", ranking, ["case", "target", "method", "seconds",
                                                "relative", "at_most"])
    print("\ncost at equal energy error (interpolated; relative to the fastest of the case)")
    print(f"{'case':8s} {'target':>7s}  ranking")
    for case in dict.fromkeys(r["case"] for r in ranking):
        for target in TARGETS:
            sel = [r for r in ranking if r["case"] == case and r["target"] == target]
            if sel:
                print(f"{case:8s} {target:7.0e}  " + ", ".join(
                    f"{r['method']} {'≤' if r['at_most'] else ''}{r['relative']:.2f}"
                    for r in sel))
    print("(≤: every run of that ladder is below the target; the cost of its cheapest run)")
    return rows, ranking


# -- the speed targets ------------------------------------------------------
@njit(cache=True)
def plain_kg_loop(q, p, dq, dp, d, c, kinds, coefs, tau, steps):
    """The same algorithm as varint's TM stepper on a fixed-end KG chain
    with one deviation vector, written as a plain loop: every stage of the
    scheme (drift: kinds 0, kick: 1), the vector normalised every step.
    Returns Σ log‖w‖ (so X₁ = that / t). ``d`` is ε̃ + 2/W, ``c`` is 1/W."""
    n = q.shape[0]
    total = 0.0
    for _ in range(steps):
        for i in range(kinds.shape[0]):
            h = coefs[i] * tau
            if kinds[i] == 0:
                for s in range(n):
                    q[s] += h * p[s]
                    dq[s] += h * dp[s]
            else:
                for s in range(n):
                    left = q[s - 1] if s > 0 else 0.0
                    right = q[s + 1] if s < n - 1 else 0.0
                    dleft = dq[s - 1] if s > 0 else 0.0
                    dright = dq[s + 1] if s < n - 1 else 0.0
                    p[s] -= h * ((d[s] + q[s] * q[s]) * q[s] - c * (left + right))
                    dp[s] -= h * ((d[s] + 3.0 * q[s] * q[s]) * dq[s] - c * (dleft + dright))
        norm = 0.0
        for s in range(n):
            norm += dq[s] * dq[s] + dp[s] * dp[s]
        norm = math.sqrt(norm)
        total += math.log(norm)
        for s in range(n):
            dq[s] /= norm
            dp[s] /= norm
    return total


def plain_loop_ratio(n, steps, repeats=3):
    """varint's time per step over the plain loop's, on a KG chain of ``n``
    sites (ABA864, τ = 0.05, one vector, "x1"), and both X₁ (which must
    agree: the loop is the same algorithm)."""
    from varint.schemes import DRIFT

    model = DisorderedKG(n, 4.0, 1)
    x0 = model.initial_block(21, 0.1, seed=1)
    w0 = np.random.default_rng(2).standard_normal(model.dim)
    w0 /= np.linalg.norm(w0)
    stages = varint.get_scheme("ABA864").stages()
    kinds = np.array([0 if kind == DRIFT else 1 for kind, _ in stages], dtype=np.int64)
    coefs = np.array([coef for _, coef in stages])
    d = model.epsilon + 2.0 / model.W
    tau = 0.05

    def plain():
        q, pp = x0[:n].copy(), x0[n:].copy()
        dq, dp = w0[:n].copy(), w0[n:].copy()
        return plain_kg_loop(q, pp, dq, dp, d, 1.0 / model.W, kinds, coefs, tau, steps)

    def ours():
        return varint.run(model, x0, "x1", steps * tau, tau, scheme="ABA864",
                          deviations=w0[:, None], t_out=1, progress=False)

    plain(), ours()                                   # compile both
    best = {"plain": math.inf, "varint": math.inf}
    for _ in range(repeats):                          # interleaved
        for name, f in (("plain", plain), ("varint", ours)):
            t0 = time.perf_counter()
            out = f()
            best[name] = min(best[name], time.perf_counter() - t0)
            if name == "plain":
                x1_plain = out / (steps * tau)
            else:
                x1_ours = float(out.exponents[-1, 0])
    return best["varint"] / best["plain"], best, x1_plain, x1_ours

def throughput(quick, claims):
    """Seconds per step of the KG lattices with one deviation vector
    (ABA864, τ = 0.05, the "dvd" indicator), and the time to t = 1e5 that
    this rate gives for the 100 × 100 lattice (the whole run is measured by
    :func:`kg2d_run`)."""
    rows = []
    steps = 400 if quick else 4000
    for shape in ((32, (20, 20)) if quick else (1024, (100, 100))):
        model = DisorderedKG(shape, 10.0 if isinstance(shape, tuple) else 4.0, 1)
        x0 = model.initial_block(5 if isinstance(shape, tuple) else 21, 0.1, seed=1)
        varint.run(model, x0, "dvd", 1.0, 0.05, scheme="ABA864", progress=False)
        best = math.inf
        for _ in range(3):
            t0 = time.perf_counter()
            varint.run(model, x0, "dvd", steps * 0.05, 0.05, scheme="ABA864", t_out=4,
                       progress=False)
            best = min(best, time.perf_counter() - t0)
        per_step = best / steps
        rows.append({"model": model.name, "sites": model.n_sites, "steps": steps,
                     "seconds_per_step": per_step,
                     "ns_per_site_step": 1e9 * per_step / model.n_sites,
                     "minutes_to_1e5": per_step * 1e5 / 0.05 / 60})
        print(f"{model.name}: {1e6 * per_step:.1f} µs per step, "
              f"{rows[-1]['ns_per_site_step']:.1f} ns per site and step; t = 1e5 at τ = 0.05 "
              f"in {rows[-1]['minutes_to_1e5']:.1f} min", flush=True)
    n, steps = (64, 2000) if quick else (1024, 20000)
    ratio, best, x1_plain, x1_ours = plain_loop_ratio(n, steps)
    rows.append({"model": f"KG 1D N = {n}: varint / plain compiled loop", "sites": n,
                 "steps": steps, "seconds_per_step": best["varint"] / steps,
                 "ns_per_site_step": 1e9 * best["varint"] / steps / n,
                 "plain_ns_per_site_step": 1e9 * best["plain"] / steps / n, "ratio": ratio,
                 "x1_plain": x1_plain, "x1_varint": x1_ours})
    print(f"KG 1D N = {n}, ABA864, one vector: varint {rows[-1]['ns_per_site_step']:.2f} ns, "
          f"plain loop {rows[-1]['plain_ns_per_site_step']:.2f} ns per site and step "
          f"(ratio {ratio:.2f}); X1 {x1_ours:.10g} vs {x1_plain:.10g}", flush=True)
    if not quick:
        claims.add("KG 1D, N = 1024, one deviation vector: cost per site and step ≤ 1.2× a "
                   "plain compiled loop of the same step", paper="≤ 1.2 (issue target)",
                   ours=f"{ratio:.2f} ({rows[-1]['ns_per_site_step']:.2f} vs "
                        f"{rows[-1]['plain_ns_per_site_step']:.2f} ns)", holds=ratio <= 1.2,
                   note="the plain loop is numba, in this study; wall times, interleaved, "
                        "best of 3")
        # The 2D target is measured by a whole run: --part kg2d.
    return rows


def kg2d_run(quick, claims):
    """The issue's 2D target measured, not extrapolated: the 100 × 100 KG
    lattice of :func:`throughput` (W = 10, a 5 × 5 central block at energy
    density 0.1, seed 1), one deviation vector ("dvd"), ABA864 at τ = 0.05,
    run to t = 1e5 on one thread; wall and CPU seconds of the run
    (compilation excluded), its Λ and energy error."""
    shape, t_end = ((20, 20), 100.0) if quick else ((100, 100), 1e5)
    model = DisorderedKG(shape, 10.0, 1)
    x0 = model.initial_block(5, 0.1, seed=1)
    varint.run(model, x0, "dvd", 1.0, 0.05, scheme="ABA864", progress=False)  # compile
    wall, cpu = time.perf_counter(), time.process_time()
    r = varint.run(model, x0, "dvd", t_end, 0.05, scheme="ABA864", progress=False)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    row = {"model": model.name, "sites": model.n_sites, "t_end": t_end, "wall_s": wall,
           "cpu_s": cpu, "mlce": float(r["x1"][-1]),
           "energy_error": float(np.max(r.energy_error))}
    print(f"{model.name} to t = {t_end:g}: {wall / 60:.2f} min wall, {cpu / 60:.2f} min CPU; "
          f"Λ = {row['mlce']:.3g}, energy error {row['energy_error']:.2g}", flush=True)
    if not quick:
        claims.add("KG 2D 100 × 100, one deviation vector, ABA864, τ = 0.05, to t = 1e5 on "
                   "one core in ≤ 10 minutes, measured", paper="≤ 10 min (issue target)",
                   ours=f"{wall / 60:.2f} min wall ({cpu / 60:.2f} min CPU)",
                   holds=wall <= 600, note="one run, one thread, on the shared 2-core machine")
    return row


# -- part (b): chaos laws -------------------------------------------------------
#: (name, model class, params, (block width, density), scheme, τ, horizon,
#: law of Λ, law of m₂, source)
LAWS = [
    ("KG 1D weak chaos", DisorderedKG, {"shape": 512, "W": 4.0},
     (1, 0.4), "ABA864", 0.2, 1e6, -0.25, 1 / 3,
     "FKS09 (m₂ ∝ t^1/3); SMS18 (Λ ∝ t^−0.25)"),
    ("DDNLS 1D weak chaos", DDNLS, {"shape": 256, "W": 4.0, "beta": 0.04},
     (21, 1.0), "s9ABC6", 0.2, 1e5, -0.25, 1 / 3,
     "FKS09 (m₂ ∝ t^1/3); SMS18 (Λ ∝ t^−0.25)"),
    ("DDNLS 1D strong chaos", DDNLS, {"shape": 256, "W": 3.5, "beta": 0.72},
     (21, 1.0), "s9ABC6", 0.2, 1e5, -0.3, 1 / 2,
     "Laptyeva et al. 2010 (m₂ ∝ t^1/2, then 1/3); SMS18 (Λ ∝ t^−0.3)"),
    ("KG 2D weak chaos", DisorderedKG, {"shape": (41, 41), "W": 10.0},
     (1, 0.4), "ABA864", 0.2, 1e5, -0.37, 1 / 5,
     "MSS20 (m₂ ∝ t^1/5, Λ ∝ t^−0.37)"),
]


def laws(quick, out, claims):
    seeds = range(1, 3) if quick else range(1, 7)
    rows = []
    for name, cls, params, (width, density), scheme, tau, t_end, law_x1, law_m2, source \
            in LAWS:
        if quick:
            params = dict(params, shape=32 if isinstance(params["shape"], int) else (9, 9))
            width, t_end = min(width, 5), 200.0
        t_out = np.geomspace(2.0, t_end, 41)
        t0 = time.perf_counter()
        e = varint.ensemble(cls, seeds, lambda m, s, w=width, d=density:
                            m.initial_block(w, d, seed=s),
                            "dvd", t_end, tau, params=params, scheme=scheme, t_out=t_out,
                            progress=False,
                            checkpoint=Path(out) / "lattices_ensembles" / name.replace(" ", "_"))
        sec = time.perf_counter() - t0
        window = (t_end / 100, t_end)
        row = {"case": name, "params": str(params), "excitation": f"L={width}, density {density}",
               "scheme": scheme, "tau": tau, "t_end": t_end, "realisations": len(seeds),
               "seconds": sec, "max_energy_error": float(np.nanmax(np.abs(e.energy_error)))}
        for what, law in (("x1", law_x1), ("m2", law_m2)):
            fit = e.exponent(what, window)
            judged = exponent_law(fit["a"], fit["a_err"], law, window)
            row.update({f"{what}_exponent": fit["a"], f"{what}_spread": fit["a_std"],
                        f"{what}_stderr": fit["a_err"], f"{what}_paper": law})
            label = "Λ" if what == "x1" else "m₂"
            claims.add(f"{name}: {label} ∝ t^{law:.2g}",
                       paper=f"{law:.3g} ({source})",
                       ours=f"{fit['a']:.3f} ± {fit['a_err']:.3f} (spread {fit['a_std']:.2f}), "
                            f"t = {window[0]:.0e}–{window[1]:.0e}, {len(seeds)} realisations",
                       holds=judged.holds, rules=[judged],
                       note=f"ours: {params}, {scheme} τ = {tau}; papers fit far later times "
                            "(to 1e9 and beyond) over 50–100 realisations")
        rows.append(row)
        print(f"{name:22s} t ≤ {t_end:.0e}, R = {len(seeds)}: Λ ∝ t^{row['x1_exponent']:.3f}"
              f" ± {row['x1_stderr']:.3f} (paper {law_x1:g}), m₂ ∝ t^{row['m2_exponent']:.3f}"
              f" ± {row['m2_stderr']:.3f} (paper {law_m2:.3g}); max |ΔH/H| "
              f"{row['max_energy_error']:.1e}; {sec:.0f} s", flush=True)
    save_csv(out, "lattices_laws", rows, list(rows[0]))
    return rows


def main(argv=None):
    def extra(parser):
        parser.add_argument("--part", choices=("all", "efficiency", "laws", "kg2d"),
                            default="all", help="efficiency (and speed), the chaos laws, or "
                            "the 2D KG run to t = 1e5 (kg2d, not part of all); default "
                            "efficiency and laws")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    out = {}
    if args.part in ("all", "efficiency"):
        claims = Claims("lattices", args.out, source="own")
        out.update(_efficiency_part(args, claims))
        claims.save()
    if args.part in ("all", "laws"):
        claims = Claims("lattices_laws", args.out, source="own")
        out["laws"] = laws(args.quick, args.out, claims)
        claims.save()
    if args.part == "kg2d":
        claims = Claims("lattices_kg2d", args.out, source="own")
        out["kg2d"] = kg2d_run(args.quick, claims)
        claims.save()
    save_json(args.out, f"lattices_{args.part}", dict(out, quick=args.quick))
    return out


def _efficiency_part(args, claims):
    rows, ranking = efficiency(args.quick, args.out)
    for case, best in D19_BEST.items():
        for target, names in best.items():
            sel = [r for r in ranking if r["case"] == case and r["target"] == target]
            if not sel:
                continue
            winner = sel[0]["method"]
            tm_only = [r for r in sel if r["method"] not in ("DOP853", "Taylor (heyoka)")]
            claims.add(f"D19: the most efficient scheme for {case} at energy error "
                       f"{target:.0e}", paper=" or ".join(sorted(names)),
                       ours=f"{winner} (then " + ", ".join(
                           f"{r['method']} ×{r['relative']:.2f}" for r in sel[1:4]) + ")",
                       holds=tm_only[0]["method"] in names if tm_only else None,
                       note="our lattice, horizon and initial state; s19ABC8's coefficients "
                            "were not found in any reachable source, so it is not run")
    for case in ("fput", "kg"):
        for target in TARGETS:
            sel = {r["method"]: r for r in ranking
                   if r["case"] == case and r["target"] == target}
            tm = [r for k, r in sel.items() if k not in ("DOP853", "Taylor (heyoka)")]
            hy = sel.get("Taylor (heyoka)")
            if tm and hy is not None:
                best = min(tm, key=lambda r: r["seconds"])
                ratio = hy["seconds"] / best["seconds"]
                # A cost that is only a bound makes the ratio one too.
                sign = "≤ " if hy["at_most"] and not best["at_most"] else \
                    "≥ " if best["at_most"] and not hy["at_most"] else ""
                claims.add(f"{case}: TM at least 5× faster than heyoka at energy error "
                           f"{target:.0e}", paper="≥ 5 (issue target)",
                           ours=f"{sign}{ratio:.2f} (TM: {best['method']})",
                           holds=None if (sign == "≤ ") == (ratio >= 5) and sign else
                           ratio >= 5,
                           note="wall-time ratio at the interpolated equal energy error; "
                                "heyoka's Taylor method on var_ode_sys, one vector")
    speed = throughput(args.quick, claims)
    return {"efficiency": rows, "ranking": ranking, "speed": speed}


if __name__ == "__main__":
    main()
