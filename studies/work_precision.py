"""Run time against error: work–precision diagrams of the TM method (every
scheme, several τ), the TDH methods, heyoka's Taylor method, CVODE and
DOP853 (several tolerances), with the Pareto front, the crossover points
and where a baseline beats TM.

Cases (full mode; ``--quick`` shortens the horizons and thins the
configurations):

* ``tangent_R1``: relative error of the raw deviation vectors at t = 1e3 on R1.
* ``tangent_C1``: the same on C1 at t = 300. At t = 1e3 every
  double-precision method, and the long-double reference, is O(1) off on C1
  (measured here against quadruple precision), so no diagram exists there;
  300 is where the reference is still 4000× better than double round-off.
* ``energy_R1``: largest relative energy error up to t = 1e4 on R1 while
  computing the full Lyapunov spectrum (QR every τ), the setting of Table I.
* ``x1_C1``: |X1 − X1,ref| at t = 300 on C1 (one vector, normalised every τ).
* ``gali_R1``: max_k |Δ log10 GALI_k|, k = 2, 3, 4, at t = 1e3 on R1.

Errors are against the extended-precision Taylor reference
(:mod:`studies.accuracy`). Cost is the wall time of the run loop (the
minimum over three runs, one if a run takes longer than 10 s; compilation
and set-up excluded; the CPU time is in the CSV too) and the number of
force evaluations: ∇V (with D²V) for
TM and TDH, right-hand sides for DOP853 and CVODE (CVODE's
finite-difference Jacobians included, one right-hand side per state
component each). heyoka's Taylor method evaluates neither (each step
computes Taylor coefficients of every term to order ~20), so it appears in
the time panels only. The machine is shared by several developers and
timings are noisy: only ratios within one run mean anything (each row also
gives its time relative to TM SBAB2C at τ = 0.05 in the same run). This is a
benchmark: it prints and plots, it asserts nothing about time.

Usage: ``python studies/work_precision.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.accuracy import (TDH, TAU_REF, Config, Resume, deviations0,  # noqa: E402
                              evaluations, grid_times, observe, quad_reference,
                              raw_reference, relative_error, tm_configs)
from studies.common import Claims, figure, parse_args, save_csv, save_json  # noqa: E402
from varint.cache import reference  # noqa: E402
from varint.indicators import gali_from_vectors  # noqa: E402


@dataclass(frozen=True)
class Case:
    """One error measure at one horizon."""

    name: str
    orbit: str
    t_end: float
    renorm: str
    k: int
    error: str


CASES = [Case("tangent_R1", "R1", 1e3, "none", 4, "relative tangent error"),
         Case("tangent_C1", "C1", 300.0, "none", 4, "relative tangent error"),
         Case("energy_R1", "R1", 1e4, "qr", 4, "max relative energy error"),
         Case("x1_C1", "C1", 300.0, "qr", 1, "|X1 − X1,ref|"),
         Case("gali_R1", "R1", 1e3, "normalize", 4, "max |Δ log10 GALI_k|, k = 2…4")]
#: Horizons of the quick mode.
QUICK_T = {"tangent_R1": 100.0, "tangent_C1": 100.0, "energy_R1": 400.0, "x1_C1": 100.0,
           "gali_R1": 100.0}

TM_TAUS = tuple(TAU_REF * 2.0 ** j for j in range(3, -5, -1))  # 0.8 … 0.00625
TDH_TAUS = (0.2, 0.1, 0.05, 0.025)
#: The baselines choose their own steps; τ is their output (and
#: renormalisation) interval, the paper's 0.05.
BASELINE_TAU = 0.05
TAYLOR_TOLS = (1e-6, 1e-9, 1e-12, None)
CVODE_TOLS = (1e-6, 1e-8, 1e-10, 1e-12, 1e-13)
#: DOP853 restarted every τ: below its natural step (0.9 at δ = 1e-5) every
#: interval is one step truncated to τ, so τ sets the error (the paper's
#: regime) ...
DOP853_TAUS = (0.8, 0.4, 0.2, 0.1, 0.05)
#: ... and with a long interval δ does (natural steps).
DOP853_NATURAL_TAU = 0.8
DOP853_DELTAS = (1e-7, 1e-9, 1e-11, 1e-13)

#: The configuration every time is compared with, in the same run.
BASE = ("TM SBAB2C", 0.05)
REPEATS = 3
REPEAT_LIMIT = 10.0


@dataclass(frozen=True)
class Point:
    """A configuration at one τ."""

    config: Config
    tau: float

    @property
    def label(self):
        return f"{self.config.label} τ={self.tau:g}"


def series(pt):
    """The line a configuration belongs to in the diagrams: one per TM
    scheme, per TDH method, per baseline and DOP853 regime."""
    c = pt.config
    if c.family == "TM":
        return c.label
    if c.family == "DOP853":
        return ("DOP853 δ=1e-5, τ varies" if pt.tau != DOP853_NATURAL_TAU or
                c.opts()["delta"] == 1e-5 else f"DOP853 τ={DOP853_NATURAL_TAU:g}, δ varies")
    return c.family


def points(quick):
    """Every configuration of the diagrams."""
    schemes = ("SABA2", "SBAB2C", "ABA864", "SRKN14a") if quick else None
    tm_taus = (0.2, 0.1, 0.05) if quick else TM_TAUS
    pts = [Point(c, tau) for c in tm_configs(schemes) for tau in tm_taus]
    pts += [Point(c, tau) for c in TDH for tau in ((0.1, 0.05) if quick else TDH_TAUS)]
    for tol in ((1e-6, 1e-10, None) if quick else TAYLOR_TOLS):
        opts = () if tol is None else (("tol", tol),)
        pts.append(Point(Config(f"Taylor double tol={tol or 'ε'}", "taylor", opts, "Taylor"),
                         BASELINE_TAU))
    for tol in ((1e-6, 1e-8, 1e-10) if quick else CVODE_TOLS):
        pts.append(Point(Config(f"CVODE {tol:g}", "cvode", (("rtol", tol), ("atol", tol)),
                                "CVODE"), BASELINE_TAU))
    for tau in ((0.4, 0.2) if quick else DOP853_TAUS):
        pts.append(Point(Config("DOP853 δ=1e-5", "dop853", (("delta", 1e-5),), "DOP853"), tau))
    for delta in ((1e-8, 1e-11) if quick else DOP853_DELTAS):
        pts.append(Point(Config(f"DOP853 δ={delta:g}", "dop853", (("delta", delta),),
                                "DOP853"), DOP853_NATURAL_TAU))
    return pts


# -- the error of one run -----------------------------------------------------

def case_reference(case, model, x0, W0, t_end):
    """What a run is compared with (cached extended-precision references)."""
    if case.renorm == "none":
        return raw_reference(model, x0, W0, [t_end])[1][0]
    if case.name.startswith("energy"):
        return None
    if case.renorm == "qr":
        return reference(model, x0, t_end, tau=TAU_REF, kind="lyapunov_spectrum",
                         deviations=W0, t_out=[t_end]).exponents[-1]
    return {k: v[-1] for k, v in reference(
        model, x0, t_end, tau=TAU_REF, kind="gali", k=tuple(range(2, W0.shape[1] + 1)),
        deviations=W0, t_out=[t_end]).gali.items()}


def case_error(case, obs, ref, t_end):
    if case.renorm == "none":
        return float(relative_error(obs.W[-1:], ref[None])[0])
    if case.name.startswith("energy"):
        return float(np.max(obs.energy_error))
    if case.renorm == "qr":
        return float(abs(obs.growth[-1, 0] / t_end - ref[0]))
    g = gali_from_vectors(obs.W[-1:], tuple(ref))
    return float(max(abs(np.log10(g[k][0]) - np.log10(ref[k])) for k in ref))


def measure(case, pt, t_end, repeats):
    model, x0 = varint.paper_orbit(case.orbit)
    W0 = deviations0(model)[:, :case.k]
    # The energy is watched all along; the other errors are read at t_end.
    times = grid_times(t_end, per_decade=10) if case.name.startswith("energy") \
        else np.array([t_end])
    ref = case_reference(case, model, x0, W0, t_end)
    obs = observe(pt.config, model, x0, W0, pt.tau, times, renorm=case.renorm,
                  repeats=repeats, repeat_limit=REPEAT_LIMIT)
    with np.errstate(all="ignore"):
        err = math.nan if obs.failed else case_error(case, obs, ref, t_end)
    # For the energy: the largest error up to t_end/10, to tell a bounded
    # error from a drift.
    early = (float(np.max(obs.energy_error[times <= t_end / 10]))
             if case.name.startswith("energy") and not obs.failed else None)
    ev = evaluations(obs.counts, model.dim * (1 + case.k))
    opts = pt.config.opts()
    tol = opts.get("rtol", opts.get("delta", opts.get("tol")))
    if pt.config.method == "taylor" and tol is None:
        tol = float(np.finfo(float).eps)
    return {"case": case.name, "config": pt.config.label, "family": pt.config.family,
            "series": series(pt), "tau": pt.tau, "tolerance": tol, "label": pt.label,
            "error": err, "seconds": obs.seconds, "cpu_seconds": obs.cpu_seconds,
            "ms_per_tu": 1e3 * obs.seconds / t_end, "evaluations": ev,
            "evaluations_per_tu": None if ev is None else ev / t_end,
            "taylor_steps": obs.counts.get("taylor_steps"), "error_to_t_end_over_10": early,
            "failed": obs.failed}


# -- Pareto front and crossovers ----------------------------------------------

def pareto(rows, cost):
    """Rows on the Pareto front of (``cost``, error): no other row is both
    cheaper and at least as accurate. Sorted by cost."""
    usable = sorted((r for r in rows if _ok(r, cost)), key=lambda r: (r[cost], r["error"]))
    front = []
    for r in usable:
        # Identical points (TDH and TM share an orbit, hence its energy
        # error) do not dominate each other: both stay.
        if not front or r["error"] < front[-1]["error"] or (
                (r["error"], r[cost]) == (front[-1]["error"], front[-1][cost])):
            front.append(r)
    return front


#: Errors at or above this (no digit right; unstable steps reach 1e44) are
#: kept in the tables but left out of fronts, envelopes and figures.
MAX_ERROR = 1.0


def _ok(row, cost):
    return (row.get(cost) is not None and 0 < row["error"] < MAX_ERROR
            and np.isfinite(row[cost]))


def envelope(rows, cost, levels):
    """Cheapest ``cost`` reaching an error ≤ each level (inf where none
    does), and which row achieves it."""
    usable = sorted((r for r in rows if _ok(r, cost)), key=lambda r: r["error"])
    out, who = np.full(len(levels), math.inf), [None] * len(levels)
    for j, level in enumerate(levels):
        for r in usable:
            if r["error"] > level:
                break
            if r[cost] < out[j]:
                out[j], who[j] = r[cost], r
    return out, who


def winners(rows, cost, n_levels=400):
    """The cheapest family at each error level (the lowest envelope), as
    segments from the largest error reached to the smallest:
    [(e_hi, e_lo, family, label)], with the label of the configuration
    that is cheapest at e_lo. A boundary between segments is a crossover."""
    errs = [r["error"] for r in rows if _ok(r, cost)]
    if not errs:
        return []
    levels = np.geomspace(max(errs), min(errs), n_levels)
    families = sorted({r["family"] for r in rows if _ok(r, cost)})
    env = {f: envelope([r for r in rows if r["family"] == f], cost, levels) for f in families}
    segments = []
    for j, level in enumerate(levels):
        fam = min(families, key=lambda f: env[f][0][j])
        if not segments or segments[-1][2] != fam:
            segments.append([level, level, fam, None])
        segments[-1][1] = level
        segments[-1][3] = env[fam][1][j]["label"]
    return [tuple(s) for s in segments]


def beats_tm(rows, cost, n_levels=400):
    """For each baseline family: the error levels at which it is cheaper
    than every TM configuration (or reaches where TM does not), as ranges."""
    errs = [r["error"] for r in rows if _ok(r, cost)]
    if not errs:
        return {}
    levels = np.geomspace(max(errs), min(errs), n_levels)
    tm, _ = envelope([r for r in rows if r["family"] == "TM"], cost, levels)
    out = {}
    for fam in ("Taylor", "CVODE", "DOP853"):
        env, _ = envelope([r for r in rows if r["family"] == fam], cost, levels)
        better = env < tm
        ranges, j = [], 0
        while j < len(levels):
            if better[j]:
                k = j
                while k + 1 < len(levels) and better[k + 1]:
                    k += 1
                ranges.append((float(levels[j]), float(levels[k])))
                j = k + 1
            else:
                j += 1
        out[fam] = ranges
    return out


def ratios_to_tm(rows, cost):
    """For each baseline family, the range of its ``cost`` divided by that of
    the cheapest TM configuration at least as accurate (at equal error; a
    ratio below 1: the baseline is cheaper). Points more accurate than any TM
    configuration have no ratio."""
    tm = [r for r in rows if r["family"] == "TM" and _ok(r, cost)]
    out = {}
    for fam in ("Taylor", "CVODE", "DOP853"):
        ratios = []
        for r in rows:
            if r["family"] == fam and _ok(r, cost):
                cheaper = [t[cost] for t in tm if t["error"] <= r["error"]]
                if cheaper:
                    ratios.append(r[cost] / min(cheaper))
        out[fam] = (min(ratios), max(ratios)) if ratios else None
    return out


def describe_segments(segments):
    return "; ".join(f"{fam} for errors {hi:.1e}…{lo:.1e} (down to it: {label})"
                     for hi, lo, fam, label in segments)


def describe_beats(beats):
    parts = []
    for fam, ranges in beats.items():
        if ranges:
            parts.append(f"{fam} at errors " + ", ".join(f"{hi:.1e}…{lo:.1e}"
                                                        for hi, lo in ranges))
        else:
            parts.append(f"{fam} nowhere")
    return "; ".join(parts)


# -- C1 at t = 1e3 ------------------------------------------------------------

def c1_saturation(quick):
    """Tangent errors on C1 at t = 1e3 (400 with --quick) against quadruple
    precision, for the most accurate configuration of each family and the
    long-double reference itself."""
    t_end = 400.0 if quick else 1e3
    model, x0 = varint.paper_orbit("C1")
    W0 = deviations0(model)
    times = np.array([t_end])
    _, Wq = quad_reference(model, x0, W0, times)
    _, We = raw_reference(model, x0, W0, times)
    rows = [{"config": "Taylor extended (the reference)", "error":
             float(relative_error(We, Wq)[0])}]
    best = {"TM": Point(Config("TM SRKN14a", "tm", (("scheme", "SRKN14a"),), "TM"), 0.05),
            "Taylor": Point(Config("Taylor double tol=ε", "taylor", (), "Taylor"), 0.05),
            "CVODE": Point(Config("CVODE 1e-12", "cvode", (("rtol", 1e-12), ("atol", 1e-12)),
                                  "CVODE"), 0.05),
            "DOP853": Point(Config("DOP853 δ=1e-5", "dop853", (("delta", 1e-5),), "DOP853"),
                            0.05)}
    for pt in best.values():
        obs = observe(pt.config, model, x0, W0, pt.tau, times)
        rows.append({"config": pt.label, "error": float(relative_error(obs.W, Wq)[0])})
    return t_end, rows


# -- the study ----------------------------------------------------------------

def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    quick, out = args.quick, args.out
    claims = Claims("work_precision", out)
    resume = Resume(out, "work_precision", "quick" if quick else "full")
    repeats = 1 if quick else REPEATS
    pts = points(quick)
    rows = []
    for case in CASES:
        t_end = QUICK_T[case.name] if quick else case.t_end
        print(f"# {case.name}: {case.error} at t = {t_end:g} on {case.orbit}")
        for pt in pts:
            rows.append(resume.get(f"{case.name} {pt.label}",
                                   lambda case=case, pt=pt, t_end=t_end: measure(case, pt, t_end, repeats)))
    for case in CASES:
        mine = [r for r in rows if r["case"] == case.name]
        base = next(r for r in mine if (r["config"], r["tau"]) == BASE)
        for r in mine:
            r["time_vs_base"] = r["seconds"] / base["seconds"]
    save_csv(out, "work_precision", rows, list(rows[0]))

    summary = {}
    for case in CASES:
        mine = [r for r in rows if r["case"] == case.name]
        t_end = QUICK_T[case.name] if quick else case.t_end
        s = summary[case.name] = {}
        for cost in ("seconds", "evaluations"):
            front = pareto(mine, cost)
            for r in mine:
                r[f"pareto_{cost}"] = r in front
            s[cost] = {"front": [r["label"] for r in front],
                       "winners": winners(mine, cost), "beats_tm": beats_tm(mine, cost),
                       "ratio_to_tm": ratios_to_tm(mine, cost)}
        print(f"\n# {case.name}: {case.error} at t = {t_end:g} on {case.orbit}")
        print(f"{'configuration':32s} {'error':>9s} {'ms/tu':>9s} {'evals/tu':>9s} "
              f"{'vs base':>8s}  front")
        for r in sorted(mine, key=lambda r: (r["family"], r["config"], -r["tau"])):
            ev = "—" if r["evaluations_per_tu"] is None else f"{r['evaluations_per_tu']:9.3g}"
            mark = ("T" if r["pareto_seconds"] else " ") + ("E" if r["pareto_evaluations"]
                                                           else " ")
            print(f"{r['label']:32s} {r['error']:9.2e} {r['ms_per_tu']:9.3g} {ev:>9s} "
                  f"{r['time_vs_base']:8.3g}  {mark}")
        for cost, unit in (("seconds", "wall time"), ("evaluations", "force evaluations")):
            seg = s[cost]["winners"]
            print(f"cheapest by {unit}: {describe_segments(seg)}")
            print(f"baselines cheaper than every TM configuration ({unit}): "
                  f"{describe_beats(s[cost]['beats_tm'])}")
            crossings = [f"{seg[i][1]:.1e} ({seg[i][2]} → {seg[i + 1][2]})"
                         for i in range(len(seg) - 1)]
            claims.add(f"{case.name} ({case.error} at t = {t_end:g} on {case.orbit}): the "
                       f"cheapest method by {unit}", "—",
                       describe_segments(seg) + (f". Crossovers at {', '.join(crossings)}"
                                                 if crossings else ""), None,
                       figure=f"work_precision_{case.name}.png")
            claims.add(f"{case.name}: where a baseline beats TM by {unit}", "—",
                       describe_beats(s[cost]["beats_tm"]), None,
                       figure=f"work_precision_{case.name}.png")
        ratio = s["seconds"]["ratio_to_tm"]
        text = "; ".join(f"{fam} {lo:.3g}–{hi:.3g}×" for fam, v in ratio.items()
                         if v is not None for lo, hi in [v])
        print(f"wall time at equal error, relative to the cheapest TM configuration as "
              f"accurate: {text}")
        claims.add(f"{case.name}: wall time of the baselines at equal error, relative to the "
                   "cheapest TM configuration at least as accurate", "—", text, None,
                   figure=f"work_precision_{case.name}.png")
        plot(out, case, mine, t_end, s)
    save_csv(out, "work_precision", rows, list(rows[0]))

    t_sat, sat = resume.get("C1 saturation", lambda: c1_saturation(quick))
    print(f"\n# C1 at t = {t_sat:g} against quadruple precision (relative tangent error)")
    for r in sat:
        print(f"{r['config']:36s} {r['error']:.2e}")
    claims.add(f"C1: the global tangent error at t = {t_sat:g} cannot be measured for any "
               "double-precision method: all are O(1) off, as is the long-double reference",
               "long double O(1) off at t ≈ 700–1000 (FINDINGS)",
               "; ".join(f"{r['config']} {r['error']:.1e}" for r in sat),
               None if quick else all(r["error"] > 0.1 for r in sat))
    claims.save()
    result = {"rows": rows, "summary": summary, "c1_saturation": {"t": t_sat, "rows": sat},
              "claims": claims.items}
    save_json(out, "work_precision", {k: v for k, v in result.items() if k != "rows"})
    resume.finish()
    return result


# -- figures ------------------------------------------------------------------

#: TM schemes drawn in colour (blues and greens), the others in grey.
SHOWN = {"TM SABA2": "#6baed6", "TM SBAB2C": "#2171b5", "TM ABA864": "#08306b",
         "TM s11odr6": "#41ab5d", "TM SRKN14a": "#00441b"}
COLORS = {"TDHcc": "tab:purple", "TDHes": "tab:pink", "TDHeps": "tab:brown",
          "Taylor": "goldenrod", "CVODE": "tab:orange", "DOP853": "tab:red"}


def plot(out, case, rows, t_end, summary):
    path, plt = figure(out, f"work_precision_{case.name}")
    fig, axes = plt.subplots(1, 2, figsize=(13, 5), layout="constrained")
    for ax, cost, ylabel in ((axes[0], "ms_per_tu", "wall time per unit time (ms)"),
                             (axes[1], "evaluations_per_tu", "force / rhs evaluations per "
                                                             "unit time")):
        key = "seconds" if cost == "ms_per_tu" else "evaluations"
        for name in dict.fromkeys(r["series"] for r in rows):
            # Along a series: τ, then the tolerance, from coarse to fine.
            pts = sorted((r for r in rows if r["series"] == name and _ok(r, cost)),
                         key=lambda r: (-r["tau"], -(r["tolerance"] or 0.0)))
            if not pts:
                continue
            fam = pts[0]["family"]
            if fam == "TM":
                shown = name in SHOWN
                style = dict(color=SHOWN.get(name, "0.75"), lw=1.4 if shown else 0.6,
                             marker="o", ms=3, zorder=3 if shown else 1,
                             label=name if shown else None)
            else:
                natural = "δ varies" in name
                style = dict(color=COLORS[fam], marker="^" if natural else "s", ms=4,
                             ls=":" if natural else "--", label=name)
            ax.loglog([r["error"] for r in pts], [r[cost] for r in pts], **style)
        front = sorted((r for r in rows if r[f"pareto_{key}"]), key=lambda r: r[cost])
        if front:
            ax.plot([r["error"] for r in front], [r[cost] for r in front], "o-", color="k",
                    mfc="none", ms=9, lw=0.8, label="Pareto front", zorder=4)
        seg = summary[key]["winners"]
        for i in range(len(seg) - 1):
            ax.axvline(seg[i][1], color="k", ls=":", lw=0.8)
            ax.annotate(f"{seg[i][2]}→{seg[i + 1][2]}", (seg[i][1], ax.get_ylim()[0]),
                        rotation=90, fontsize=6, va="bottom", ha="right")
        ax.set_xlabel(case.error)
        ax.set_ylabel(ylabel)
        ax.invert_xaxis()
    axes[0].legend(fontsize=6, ncol=2)
    fig.suptitle(f"{case.name}: {case.orbit}, t = {t_end:g} (grey: the other TM schemes)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
