"""TDHeps against the paper's numbers: which reading of its Sect. V.B.3
reproduces them.

varint's TDHeps (:mod:`varint.tdh`; the paper's eqs. 32–37 and A.13–A.18 of
the LaTeX source) has the order-4 tangent error it should, yet its X1 levels
off 3.2–3.4× above the paper's on R1 (Table I) and 24× below it on R2
(Fig. 9). This study re-implements the method independently — one deviation
vector, SBAB2C at τ = 2Δt written out from Appendix eqs. A.15–A.18 and
generalised to any model with a diagonal inverse mass — checks that it gives
varint's numbers, and then varies what the paper leaves open:

* **R2, the corrector with masses.** The paper's eq. 36,
  C̃ = Σ_i (∂B̃/∂δq_i)², is the corrector {B̃, {B̃, Ã}} for unit masses only;
  with the 3D system's M⁻¹ = diag(1, √2, √3) it is δqᵀ D²V M⁻¹ D²V δq, which
  varint uses. Taking eq. 36 literally leaves an error one order lower.
* **R1, the orbit's step.** The caption of Table I says Δt = τ/2, but the
  table's energy errors at τ = 0.1, 0.2, 0.5 (1e-6, 2e-5, 1e-3) are larger
  than any error an SBAB2C orbit reaches at Δt = τ/2 and of the size it
  reaches at Δt = τ (:func:`energy_errors`). The variant integrates the orbit
  with Δt = τ and takes q(t_i + τ/2) by a half step from q(t_i).

The level of TDHeps on R1 is a near-cancellation between the tangent
scheme's error and the orbit's (changing the corrector constant g by 10 %
moves it by factors 5 to 100), so a 1.5× difference is within what a
different orbit error makes.

Usage: ``python studies/tdheps_variants.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numba
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import Claims, parse_args, save_csv  # noqa: E402
from studies import claims as rules  # noqa: E402

#: SBAB2C's corrector constant (splitting-schemes.md): the corrector map is
#: e^{−(g τ³/2) L_C} at both ends.
G_SBAB2C = 1.0 / 72.0
#: The paper's TDHeps levels: Table I (R1, X1 at 1e8) and Fig. 9 (R2, X1 at 1e6).
PAPER_R1 = {0.05: 2.3e-5, 0.1: 8.9e-5, 0.2: 3.5e-4, 0.5: 1.8e-3}
PAPER_R2 = 1.3e-3
PAPER_ENERGY = {0.1: 1e-6, 0.2: 2e-5, 0.5: 1e-3}


def make_tdheps(model, orbit_step="half", unit_mass_corrector=False):
    """A compiled TDHeps run (one deviation vector, normalised every τ).

    Parameters
    ----------
    model : Model
    orbit_step : {"half", "full"}
        "half": the orbit steps Δt = τ/2 and the grid gives q(t_i),
        q(t_i + τ/2), q(t_i + τ) (the paper's caption; varint's method).
        "full": the orbit steps Δt = τ, and q(t_i + τ/2) comes from a
        half step from the orbit at t_i.
    unit_mass_corrector : bool
        Use the paper's eq. 36 literally, C̃ = |D²V δq|², instead of
        δqᵀ D²V M⁻¹ D²V δq. The orbit's corrector keeps M⁻¹.

    Returns
    -------
    callable
        ``run(x0, w0, tau, n_steps, marks) -> X1 at the steps in marks``.
    """
    grad, hess = model.grad_kernel, model.hess_kernel
    par = np.asarray(model.params, dtype=float)
    minv = np.asarray(model.inverse_mass, dtype=float)
    mcorr = np.ones_like(minv) if unit_mass_corrector else minv.copy()
    n, bw, full = model.n_dof, model.bandwidth, orbit_step == "full"
    if orbit_step not in ("half", "full"):
        raise ValueError(f"orbit_step must be 'half' or 'full', got {orbit_step!r}")

    @numba.njit
    def dense_hessian(q, band, out):
        hess(q, par, band)
        out[:, :] = 0.0
        for b in range(bw + 1):
            for i in range(n - b):
                out[i, i + b] = band[b, i]
                out[i + b, i] = band[b, i]

    @numba.njit
    def orbit_step_(x, h, g, band, hf):
        # SBAB2C on the orbit: corrector, B(h/6) A(h/2) B(2h/3) A(h/2) B(h/6),
        # corrector; the corrector map e^{−(g h³/2) L_C} with ∇C = 2 D²V M⁻¹ ∇V.
        q, p, gv = x[:n], x[n:], np.empty(n)
        grad(q, par, gv)
        dense_hessian(q, band, hf)
        p += g * h ** 3 * (hf @ (minv * gv)) - h / 6 * gv
        q += h / 2 * minv * p
        grad(q, par, gv)
        p -= 2 * h / 3 * gv
        q += h / 2 * minv * p
        grad(q, par, gv)
        dense_hessian(q, band, hf)
        p += g * h ** 3 * (hf @ (minv * gv)) - h / 6 * gv

    @numba.njit
    def run(x0, w0, tau, n_steps, marks):
        x, w = x0.copy(), w0 / np.linalg.norm(w0)
        band, hf = np.zeros((bw + 1, n)), np.zeros((n, n))
        h0, hm, h1 = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
        c = -G_SBAB2C * tau ** 3 / 2  # the corrector map's coefficient
        dense_hessian(x[:n], band, h1)
        out, log_sum, k = np.zeros(marks.size), 0.0, 0
        for step in range(1, n_steps + 1):
            h0[:, :] = h1
            if full:
                mid = x.copy()
                orbit_step_(mid, tau / 2, G_SBAB2C, band, hf)
                dense_hessian(mid[:n], band, hm)
                orbit_step_(x, tau, G_SBAB2C, band, hf)
            else:
                orbit_step_(x, tau / 2, G_SBAB2C, band, hf)
                dense_hessian(x[:n], band, hm)
                orbit_step_(x, tau / 2, G_SBAB2C, band, hf)
            dense_hessian(x[:n], band, h1)
            dq, dp = w[:n], w[n:]
            # eqs. 35 and 37: kicks by D²V(q(t)) δq and by ∇C̃ = 2 D²V M⁻¹ D²V δq
            dp -= 2 * c * (h0 @ (mcorr * (h0 @ dq))) + tau / 6 * (h0 @ dq)
            dq += tau / 2 * minv * dp
            dp -= 2 * tau / 3 * (hm @ dq)
            dq += tau / 2 * minv * dp
            dp -= tau / 6 * (h1 @ dq) + 2 * c * (h1 @ (mcorr * (h1 @ dq)))
            norm = math.sqrt(np.sum(w * w))
            log_sum += math.log(norm)
            w /= norm
            if k < marks.size and step == marks[k]:
                out[k] = log_sum / (step * tau)
                k += 1
        return out

    return run


def levels(model, x0, tau, t_end, n_out=25, **variant):
    """Times and X1 of the variant at ``n_out`` log-spaced steps to
    ``t_end``, from one vector along (1, …, 1)/√(2N)."""
    n_steps = int(round(t_end / tau))
    marks = np.unique(np.geomspace(1, n_steps, n_out).round().astype(np.int64))
    w0 = np.ones(model.dim) / math.sqrt(model.dim)
    ours = make_tdheps(model, **variant)(np.asarray(x0, dtype=float), w0, tau, n_steps, marks)
    return marks * tau, ours


def library_x1(model, x0, tau, t):
    """varint's TDHeps X1 at the times ``t``, from the vector of :func:`levels`."""
    w0 = np.ones((model.dim, 1)) / math.sqrt(model.dim)
    r = varint.lyapunov_spectrum(model, x0, t[-1], tau=tau, method="tdheps", deviations=w0,
                                 t_out=t, progress=False)
    return r.exponents[:, 0]


def energy_errors(tau, t_end):
    """Relative energy error of R1's SBAB2C orbit at Δt = τ/2 and Δt = τ up
    to ``t_end`` (sampled 200 times per decade): label -> its largest value
    over the run, and its median and largest value over the last decade
    (the band an oscillating error fills)."""
    model, x0 = varint.paper_orbit("R1")
    out = {}
    for label, dt in (("half", tau / 2), ("full", tau)):
        steps = np.unique(np.geomspace(1, t_end / dt, 200 * round(math.log10(t_end / dt))).round())
        r = varint.integrate(model, x0, t_end, tau=dt, t_out=steps * dt, progress=False)
        last = r.energy_error[r.t >= t_end / 10]
        out[label] = {"max": float(np.max(r.energy_error)), "median": float(np.median(last)),
                      "max_last_decade": float(np.max(last))}
    return out


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    quick = args.quick
    claims = Claims("tdheps_variants", args.out)
    rows = []
    r1, x1_0 = varint.paper_orbit("R1")
    r2, x2_0 = varint.paper_orbit("R2")

    # 1. The independent implementation gives varint's TDHeps.
    t, mine = levels(r1, x1_0, 0.2, 2e3 if quick else 1e5)
    lib = library_x1(r1, x1_0, 0.2, t)
    gap = float(np.max(np.abs(mine / lib - 1)))
    claims.add("A second TDHeps, written from eqs. A.15–A.18, gives varint's X1 (R1, τ = 0.2)",
               "—", f"largest relative difference {gap:.1e} to t = {t[-1]:.0e}", gap < 1e-8)

    # 2. R1: the orbit's step.
    taus = (0.2, 0.5) if quick else (0.05, 0.1, 0.2, 0.5)
    for tau in taus:
        t_end = (2e3 if quick else 2e6) if tau == 0.05 else (2e3 if quick else 3e5)
        for step in ("half", "full"):
            t, x1 = levels(r1, x1_0, tau, t_end, orbit_step=step)
            rows.append({"orbit": "R1", "tau": tau, "orbit_step": step, "corrector": "M^-1",
                         "t_end": t[-1], "X1": x1[-1], "paper": PAPER_R1[tau],
                         "ratio": x1[-1] / PAPER_R1[tau]})
    if not quick:
        half = [r["ratio"] for r in rows if r["orbit_step"] == "half"]
        full = [r["ratio"] for r in rows if r["orbit_step"] == "full"]
        js = [rules.agrees(r["X1"], r["paper"]) for r in rows if r["orbit_step"] == "full"]
        claims.add("R1: with the orbit stepped at Δt = τ (midpoint by a half step) TDHeps' "
                   "level agrees with Table I at every τ", "2.3e-5 … 1.8e-3 at τ = 0.05 … 0.5",
                   f"ours/paper: Δt = τ {min(full):.2f}–{max(full):.2f}; Δt = τ/2 (the "
                   f"caption, varint) {min(half):.2f}–{max(half):.2f}", rules.verdict(js),
                   rules=js,
                   note="X1 read after it has levelled (t = 3e5; 2e6 at τ = 0.05); the "
                        "remaining 1.3–1.6× is within what the orbit error moves a level "
                        "that is a near-cancellation")
        for tau in PAPER_ENERGY:
            e = energy_errors(tau, 1e5)
            # Above anything the orbit at τ/2 reaches, and in the band of the
            # orbit at τ (the rule of Table I's energy errors).
            js = [rules.above(PAPER_ENERGY[tau], e["half"]["max"], "paper/largest at τ/2 "),
                  rules.in_band(PAPER_ENERGY[tau], e["full"]["median"],
                                e["full"]["max_last_decade"], (1e4, 1e5))]
            claims.add(f"R1, τ = {tau:g}: Table I's TDHeps energy error needs an orbit at Δt = τ",
                       f"{PAPER_ENERGY[tau]:.0e}",
                       f"largest error to t = 1e5: {e['half']['max']:.1e} at Δt = τ/2, "
                       f"{e['full']['max']:.1e} at Δt = τ (last decade: {js[1].text})",
                       rules.verdict(js), rules=js)

    # 3. R2: the corrector with masses.
    t_end = 2e3 if quick else 1e6
    for unit in (False, True):
        t, x1 = levels(r2, x2_0, 0.05, t_end, unit_mass_corrector=unit)
        rows.append({"orbit": "R2", "tau": 0.05, "orbit_step": "half",
                     "corrector": "unit mass (eq. 36)" if unit else "M^-1", "t_end": t[-1],
                     "X1": x1[-1], "paper": PAPER_R2, "ratio": x1[-1] / PAPER_R2})
    if not quick:
        unit = rows[-1]["X1"]
        claims.add("R2 (M⁻¹ = diag(1, √2, √3)): the paper's eq. 36 taken literally for the "
                   "TDHeps corrector gives Fig. 9's level", "X1 ≈ 1.3e-3 at t = 1e6",
                   f"unit-mass corrector {unit:.3g}; with M⁻¹ (varint) {rows[-2]['X1']:.2g}",
                   rules.agrees(unit, PAPER_R2).holds, rules=[rules.agrees(unit, PAPER_R2)],
                   note="eq. 36 is {B̃, {B̃, Ã}} only for unit masses; varint keeps M⁻¹")
    save_csv(args.out, "tdheps_variants", rows, list(rows[0]))
    for r in rows:
        print(f"{r['orbit']} tau={r['tau']:<5g} orbit step {r['orbit_step']:4s} corrector "
              f"{r['corrector']:18s} X1({r['t_end']:.0e}) = {r['X1']:.3g}  paper "
              f"{r['paper']:.2g}  ratio {r['ratio']:.2f}", flush=True)
    claims.save()
    return {"rows": rows, "claims": claims.items}


if __name__ == "__main__":
    main()
