"""The automatic step (``tau`` not given, :mod:`varint.stepsize`): which
step it chooses on the paper's five orbits and on a stiff potential none of
the defaults was tuned on, what that costs against SBAB2C at τ = 0.05 (the
pilot included), and how much a run's energy error exceeds its pilot's —
the measurement behind ``PILOT_MARGIN``.

* **Cost**: a full Lyapunov spectrum to t_end = 1e4 and 1e5, in force
  (gradient) evaluations — pilot plus run, which a faster stepper leaves in
  the same ratio — and in wall time to t_end = 1e4 (minimum of three
  interleaved repeats, compilation excluded).
* **Margin**: for each orbit, scheme (SBAB2C, ABA864, s11odr6) and the
  steps around the one the pilot picks, the largest relative energy error
  at the output times of a run to t = 1e4 divided by the pilot's (t = 100,
  50 checks). The pilot's tolerance is ``energy_tol / PILOT_MARGIN``; the
  margin must exceed the largest ratio.
* **Held-out case**: the stiff quartic V = 68 (x⁴ + y⁴ + x²y²), box orbit
  q = (1, 0.5): the step chosen, and SALI, mean MEGNO and X1 with it
  against SBAB2C at τ = 0.05.
* **Chaotic sea**: does the automatic step, which bounds the energy error
  only, bias the exponents of chaotic orbits when a higher-order scheme
  takes large steps? M states along C1, 50 time units apart, each the start
  of a run: the mean of X1(t_end) over them, with its standard error, for
  SBAB2C, ABA864, SRKN14a and s11odr6 at their automatic steps (the pilot
  on a sample of the M states, as for any batch), against ABA864 at
  τ = 0.02 (energy error ~1e-11). Every run follows its own trajectory
  after t ~ 40/χ₁, so only such means can be compared; the states are far
  apart on the orbit so that they are nearly independent samples of the
  sea. (64 copies of C1 perturbed by 1e-9 are not: they share one
  trajectory for the first ~400 time units, and their mean is close to one
  sample.) The automatic step agrees when the means differ by less than
  three combined standard errors.

Run: ``python studies/default_step.py [--quick]``.
"""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

import varint
from varint import stepsize
from varint.accuracy import DEFAULT_ENERGY_TOL, Reference
from varint.run import prepare

try:
    from common import Claims, parse_args, save_csv, save_json
    from energy_tolerance import quartic
except ImportError:  # imported as studies.default_step
    from .common import Claims, parse_args, save_csv, save_json
    from .energy_tolerance import quartic

ORBITS = ("R1", "C1", "C2", "R2", "R3")
MARGIN_SCHEMES = ("SBAB2C", "ABA864", "s11odr6")
SEA_SCHEMES = ("SBAB2C", "ABA864", "SRKN14a", "s11odr6")
SEA_REFERENCE = ("ABA864", 0.02)
SEA_SPACING = 50.0


def orbit(name):
    if name == "Q1":
        model, X = quartic()
        return model, X[0]
    return varint.paper_orbit(name)


def gradients_per_step(model, x0, scheme):
    r = varint.integrate(model, x0, 1.0, tau=0.05, scheme=scheme)
    return r.provenance.counts["gradient"] / r.provenance.counts["steps"]


def cost(name, horizons, repeats):
    """The automatic step of a Lyapunov spectrum and its cost against τ = 0.05."""
    model, x0 = orbit(name)
    row = {"orbit": name}
    prepare(model, x0, "lyapunov", horizons[0])  # compile
    start = time.perf_counter()
    job = prepare(model, x0, "lyapunov", horizons[0])  # the pilot, and little else
    choice = job.tau_choice
    row.update(tau=job.tau, pilot_gradients=choice["counts"]["gradient"],
               pilot_seconds=time.perf_counter() - start, pilots=len(choice["tried"]))
    per_step = gradients_per_step(model, x0, "SBAB2C")
    for t_end in horizons:
        tau = prepare(model, x0, "lyapunov", t_end).tau
        auto = choice["counts"]["gradient"] + round(t_end / tau) * per_step
        row[f"work_ratio_{t_end:g}"] = auto / (round(t_end / 0.05) * per_step)
    t_end = horizons[0]
    auto_s, fixed_s = [], []
    varint.lyapunov_spectrum(model, x0, 1.0, tau=0.05)  # compile
    for _ in range(repeats):  # interleaved: the machine's load hits both alike
        start = time.perf_counter()
        r = varint.lyapunov_spectrum(model, x0, t_end)
        auto_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        varint.lyapunov_spectrum(model, x0, t_end, tau=0.05)
        fixed_s.append(time.perf_counter() - start)
    row.update(seconds_auto=min(auto_s), seconds_fixed=min(fixed_s),
               time_ratio=min(auto_s) / min(fixed_s),
               energy_error=float(r.accuracy.energy_error), x1=float(r.exponents[-1, 0]))
    return row


def margins(name, t_end):
    """Run-to-pilot ratios of the largest energy error near the chosen step."""
    model, x0 = orbit(name)
    reference = Reference(model, x0[None])
    rows = []
    for scheme in MARGIN_SCHEMES:
        tau0 = prepare(model, x0, "integrate", t_end, scheme=scheme).tau
        for factor in (0.5, 1.0, 2.0, 4.0):
            tau = tau0 * factor
            counts = {}
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                pilot = stepsize._pilot(model, x0[None], tau, t_end, varint.get_scheme(scheme),
                                        reference, 1.0, counts,
                                        (np.zeros((1, model.dim, 0)), "none", None))
                run = varint.integrate(model, x0, t_end, tau=tau, scheme=scheme,
                                       t_out=None if name == "Q1" else 40, errors="flag",
                                       energy_tol=np.inf)
            if run.status != 0 or not np.isfinite(pilot) or pilot == 0:
                continue
            full = float(np.max(run.energy_error))
            rows.append({"orbit": name, "scheme": scheme, "tau": tau, "pilot_error": pilot,
                         "run_error": full, "ratio": full / pilot})
    return rows


def held_out(T):
    model, X = quartic()
    x0 = X[0]
    out = {}
    for label, tau in (("automatic", None), ("tau=0.05", 0.05)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            s = varint.sali(model, x0, T, tau=tau)
            m = varint.megno(model, x0, T, tau=tau)
            x1 = varint.lyapunov_spectrum(model, x0, T, tau=tau, n_exponents=1)
        out[label] = {"tau": s.provenance.tau, "sali": float(s.sali[-1]),
                      "mean_megno": float(m.mean_megno[-1]), "x1": float(x1.exponents[-1, 0]),
                      "energy_error": float(s.accuracy.energy_error),
                      "warned": any(issubclass(w.category, varint.accuracy.AccuracyWarning)
                                    for w in caught)}
    return out


def chaotic_sea(M, t_end):
    """X1(t_end) averaged over M states along C1 (module docstring), at each
    scheme's automatic step and at the reference step."""
    model, c1 = varint.paper_orbit("C1")
    along = varint.integrate(model, c1, SEA_SPACING * M, tau=0.01, scheme="ABA864",
                             t_out=SEA_SPACING * np.arange(1, M + 1))
    X = along.states

    def x1(scheme, tau):
        r = varint.lyapunov_spectrum(model, X, t_end, tau=tau, scheme=scheme, n_exponents=1)
        values = r.exponents[:, -1, 0]
        return {"scheme": scheme, "tau": r.provenance.tau, "x1_mean": float(values.mean()),
                "x1_se": float(values.std(ddof=1) / np.sqrt(M)),
                "energy_error": float(np.max(r.accuracy.energy_error))}

    reference = x1(*SEA_REFERENCE)
    rows = []
    for scheme in SEA_SCHEMES:
        row = x1(scheme, None)
        se = np.hypot(row["x1_se"], reference["x1_se"])
        row["z"] = (row["x1_mean"] - reference["x1_mean"]) / se
        rows.append(row)
    return {"orbits": M, "t_end": t_end, "reference": reference, "rows": rows}


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    horizons = (1e3, 1e4) if args.quick else (1e4, 1e5)
    repeats = 1 if args.quick else 3
    t_margin = 1e3 if args.quick else 1e4
    costs = [cost(name, horizons, repeats) for name in ORBITS]
    for r in costs:
        print(f"{r['orbit']}: tau = {r['tau']:.4g} ({r['pilots']} pilots, "
              f"{r['pilot_gradients']} gradients, {r['pilot_seconds']:.3f} s); work ratio "
              + ", ".join(f"{r[f'work_ratio_{t:g}']:.3f} at t = {t:g}" for t in horizons)
              + f"; time ratio {r['time_ratio']:.3f} at t = {horizons[0]:g}; energy error "
              f"{r['energy_error']:.2g}", flush=True)
    margin_rows = []
    for name in ORBITS + ("Q1",):
        margin_rows += margins(name, t_margin)
    worst = max(margin_rows, key=lambda r: r["ratio"])
    print(f"largest run/pilot energy-error ratio: {worst['ratio']:.3g} ({worst['orbit']}, "
          f"{worst['scheme']}, tau = {worst['tau']:.3g}); PILOT_MARGIN = "
          f"{stepsize.PILOT_MARGIN:g}", flush=True)
    q = held_out(500.0 if args.quick else 1e4)
    for label, v in q.items():
        print(f"stiff quartic, {label}: {v}")
    sea = chaotic_sea(*((32, 1e3) if args.quick else (128, 1e4)))
    ref = sea["reference"]
    print(f"chaotic sea ({sea['orbits']} states along C1, t = {sea['t_end']:g}): reference "
          f"{ref['scheme']} tau = {ref['tau']:g}: X1 {ref['x1_mean']:.4f} ± {ref['x1_se']:.4f}")
    for r in sea["rows"]:
        print(f"  {r['scheme']:8} automatic tau = {r['tau']:.4g}: X1 {r['x1_mean']:.4f} ± "
              f"{r['x1_se']:.4f} ({r['z']:+.2f} combined standard errors), energy error "
              f"{r['energy_error']:.2g}", flush=True)
    save_csv(args.out, "default_step_cost", costs, list(costs[0]))
    save_csv(args.out, "default_step_margin", margin_rows, list(margin_rows[0]))
    result = {"costs": costs, "margin": {"largest": worst, "rows": margin_rows,
                                         "PILOT_MARGIN": stepsize.PILOT_MARGIN},
              "held_out": q, "chaotic_sea": sea, "energy_tol": DEFAULT_ENERGY_TOL}
    save_json(args.out, "default_step", result)
    claims = Claims("default_step", args.out, source="own")
    ratio = max(r[f"work_ratio_{horizons[-1]:g}"] for r in costs)
    claims.add("On the paper's five orbits the automatic step costs at most 1.5 times SBAB2C "
               "at tau = 0.05, pilot included", paper="—",
               ours=f"largest work ratio {ratio:.3f} at t = {horizons[-1]:g}", holds=ratio <= 1.5)
    claims.add("A run's energy error exceeds its pilot's by less than PILOT_MARGIN", paper="—",
               ours=f"largest ratio {worst['ratio']:.3g}, margin {stepsize.PILOT_MARGIN:g}",
               holds=worst["ratio"] < stepsize.PILOT_MARGIN)
    auto = q["automatic"]
    regular = auto["sali"] > 1e-8 and abs(auto["mean_megno"] - 2) < 0.5
    claims.add("On the held-out stiff quartic the defaults give the right verdict (regular), "
               "and tau = 0.05 warns", paper="—",
               ours=f"automatic tau = {auto['tau']:.3g}: SALI {auto['sali']:.2g}, MEGNO "
               f"{auto['mean_megno']:.3g}; tau = 0.05 warned: {q['tau=0.05']['warned']}",
               holds=bool(regular and q["tau=0.05"]["warned"]))
    worst_z = max(sea["rows"], key=lambda r: abs(r["z"]))
    claims.add("The automatic step does not bias the mean X1 of chaotic orbits, whatever the "
               "scheme", paper="—",
               ours=f"{sea['orbits']} states along C1 to t = {sea['t_end']:g}: largest "
               f"difference from {ref['scheme']} at tau = {ref['tau']:g} "
               f"{worst_z['z']:+.2f} combined standard errors ({worst_z['scheme']}, automatic "
               f"tau = {worst_z['tau']:.3g})", holds=bool(abs(worst_z["z"]) < 3))
    claims.save()
    return result


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
