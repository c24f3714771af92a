"""The measured laws of the planetary kernels (issue 30): the Kepler
drift's tangent map against finite differences for e in [0, 0.99] and
against heyoka's variational equations over one orbit; the Wisdom–Holman
map's energy error, ετ², and with the Wisdom–Holman–Touma corrector
ετ⁴ + ε²τ²; the orders of SABA2 and ABA1064 for a small perturbation.

* Tangent vs differences: the drift of h = 0.05, 1 and 7 (beyond a period)
  from the state at true anomaly 0.3 of orbits with pericentre 0.5 and
  e = 0 … 0.99, its tangent map against fourth-order central differences
  (steps 1e-4 of each coordinate); the largest error relative to the
  largest entry.
* Tangent vs heyoka: one period of e = 0.7 as 64 drifts, the product of
  their tangent maps against heyoka's ``var_ode_sys`` of the two-body
  problem in long double at tolerance 1e-18.
* Energy errors: two planets of masses ε and 0.3ε (a = 1, 1.6; e = 0.05,
  0.02), G = 1 (inner period 2π); the largest relative energy error at 8
  outputs over 8 inner periods, for steps T/16 … T/64; with the corrector
  applied to the outputs (the map runs on C⁻¹(x₀)); the fitted slopes.

Run: ``python studies/planetary.py [--quick]``.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from varint.correctors import corrector_word
from varint.kernels import nbody
from varint.kernels.kepler import kepler_step
from varint.models import Planetary
from varint.schemes import get_scheme, part_stages

try:
    from common import Claims, figure, parse_args, save_csv, save_json
except ImportError:  # imported as studies.planetary
    from .common import Claims, figure, parse_args, save_csv, save_json

T_INNER = 2 * math.pi


def _orbit(e, f=0.3, q=0.5, mass=0.3):
    p = q * (1 + e)
    r = p / (1 + e * math.cos(f))
    c, s = math.cos(0.4), math.sin(0.4)
    pos = np.array([r * math.cos(f), r * math.sin(f) * c, r * math.sin(f) * s])
    vel = math.sqrt(1 / p) * np.array([-math.sin(f), (e + math.cos(f)) * c,
                                       (e + math.cos(f)) * s])
    return np.concatenate([pos, mass * vel])


def _drift(x, h, V=None, mass=0.3):
    y = x.copy()
    V = np.zeros((0, 6)) if V is None else V.copy()
    status = kepler_step(y, V, V.shape[0], 0, 3, 1.0, mass, h)
    if status:
        raise FloatingPointError(f"Kepler step failed with status {status}")
    return y, V


def tangent_against_differences(eccentricities, steps):
    """Rows (e, h, relative error) of the drift's tangent map against
    fourth-order central differences."""
    rows = []
    for e in eccentricities:
        for h in steps:
            x = _orbit(e)
            J = _drift(x, h, np.eye(6))[1].T
            fd = np.empty((6, 6))
            for c in range(6):
                d = 1e-4 * max(abs(x[c]), 1e-3)
                u = np.eye(6)[c] * d
                fd[:, c] = (8 * (_drift(x + u, h)[0] - _drift(x - u, h)[0])
                            - (_drift(x + 2 * u, h)[0] - _drift(x - 2 * u, h)[0])) / (12 * d)
            rows.append({"e": e, "h": h,
                         "relative_error": float(np.max(np.abs(J - fd)) / np.max(np.abs(J)))})
    return rows


def tangent_against_heyoka(e=0.7, n=64):
    """(orbit error, tangent error, ‖J‖) over one period as n drifts, against
    heyoka in long double at tol 1e-18 (errors relative to the sizes of x₀
    and of J)."""
    import heyoka as hy

    x0 = _orbit(e, f=0.0, q=0.3, mass=1.0)
    period = 2 * math.pi * (0.3 / (1 - e)) ** 1.5
    x, V = x0.copy(), np.eye(6)
    for _ in range(n):
        x, V = _drift(x, period / n, V, mass=1.0)
    q = hy.make_vars("x", "y", "z")
    v = hy.make_vars("vx", "vy", "vz")
    r3 = hy.sum([c * c for c in q]) ** 1.5
    system = [(q[i], v[i]) for i in range(3)] + [(v[i], -q[i] / r3) for i in range(3)]
    ta = hy.taylor_adaptive(hy.var_ode_sys(system, hy.var_args.vars, order=1),
                            np.concatenate([x0, np.eye(6).ravel()]).astype(np.longdouble),
                            fp_type=np.longdouble, tol=np.longdouble(1e-18))
    ta.propagate_until(np.longdouble(period))
    ref = np.asarray(ta.state, dtype=float)
    Jref = ref[6:].reshape(6, 6)
    return (float(np.max(np.abs(x - ref[:6])) / np.max(np.abs(x0))),
            float(np.max(np.abs(V.T - Jref)) / np.max(np.abs(Jref))), float(np.max(np.abs(Jref))))


def _apply(model, word, x, dt):
    parts = np.array([model.parts.index(("Kepler", "Interaction")[s]) for s, _ in word],
                     dtype=np.int64)
    h = np.array([c * dt for _, c in word])
    y = x.copy()
    status = nbody.apply_word(parts, h, y, np.zeros((0, model.dim)), 0, model.params,
                              np.empty(model.parts.n_work))
    if status:
        raise FloatingPointError(f"a corrector's Kepler step failed with status {status}")
    return y


def energy_error(eps, scheme, tau, corrector=None, periods=8):
    """The largest relative energy error of two planets of masses ε, 0.3ε
    at 8 outputs over ``periods`` inner periods."""
    model = Planetary([1.0, eps, 0.3 * eps])
    x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.02, M=2.0, inc=0.1)])
    parts, h = part_stages(get_scheme(scheme), tau, model.parts.slots(2))
    work = np.empty(model.parts.n_work)
    none = np.zeros((0, model.dim))
    y = x0 if corrector is None else _apply(model, corrector_word(corrector, True), x0, tau)
    n = int(round(periods * T_INNER / tau))
    E0 = model.energy(x0)
    worst = 0.0
    for _ in range(8):
        for _ in range(n // 8):
            nbody.apply_word(parts, h, y, none, 0, model.params, work)
        x = y if corrector is None else _apply(model, corrector_word(corrector), y, tau)
        worst = max(worst, abs(model.energy(x) - E0) / abs(E0))
    return worst


def slope(x, y):
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    eccentricities = (0.0, 0.5, 0.99) if args.quick else (0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.95,
                                                          0.99)
    fd_rows = tangent_against_differences(eccentricities, (0.05, 1.0, 7.0))
    orbit_err, tangent_err, norm_J = tangent_against_heyoka()
    taus = [T_INNER / n for n in (16, 24, 32, 48, 64)]
    rows = []
    for eps in (1e-2, 1e-3, 1e-4, 1e-5):
        for label, scheme, corrector in (("WH", "SABA1", None), ("WH + corrector 3", "SABA1", 3),
                                         ("SABA2", "SABA2", None),
                                         ("ABA1064", "ABA1064", None)):
            for tau in taus:
                rows.append({"eps": eps, "scheme": label, "tau": tau,
                             "energy_error": energy_error(eps, scheme, tau, corrector)})
    save_csv(args.out, "planetary_tangent", fd_rows, ["e", "h", "relative_error"])
    save_csv(args.out, "planetary_energy", rows, ["eps", "scheme", "tau", "energy_error"])

    def errs(eps, label, first=0):
        return [r["energy_error"] for r in rows if r["eps"] == eps and r["scheme"] == label][first:]

    fine = taus[1:4]                                       # T/24 … T/48
    slopes = {
        "WH, eps=1e-3": slope(taus, errs(1e-3, "WH")),
        "WH, eps=1e-5": slope(taus, errs(1e-5, "WH")),
        "WH + corrector 3, eps=1e-5": slope(fine, errs(1e-5, "WH + corrector 3")[1:4]),
        "WH + corrector 3, eps=1e-2": slope(taus[2:], errs(1e-2, "WH + corrector 3")[2:]),
        "SABA2, eps=1e-5": slope(fine, errs(1e-5, "SABA2")[1:4]),
    }
    linear = float(np.mean(np.array(errs(1e-3, "WH")) / np.array(errs(1e-4, "WH"))))
    quadratic = float(np.log10(errs(1e-2, "WH + corrector 3")[3]
                               / errs(1e-3, "WH + corrector 3")[3]))
    worst_fd = max(r["relative_error"] for r in fd_rows)
    result = {"tangent_vs_differences": fd_rows, "worst_tangent_vs_differences": worst_fd,
              "tangent_vs_heyoka": {"orbit": orbit_err, "tangent": tangent_err,
                                    "norm_J": norm_J, "round_off_bound": 4 * 2.2e-16 * norm_J},
              "energy": rows, "slopes": slopes, "WH_error_ratio_eps_1e-3_over_1e-4": linear,
              "corrected_error_decades_eps_1e-2_over_1e-3_at_T48": quadratic}
    save_json(args.out, "planetary", result)
    print(f"Kepler tangent vs differences, e in {eccentricities}: worst {worst_fd:.1e}")
    print(f"Kepler tangent vs heyoka over one orbit: orbit {orbit_err:.1e}, tangent "
          f"{tangent_err:.1e} of ‖J‖ = {norm_J:.0f}")
    for k, v in slopes.items():
        print(f"  slope {k}: {v:.2f}")
    print(f"  WH error ratio ε = 1e-3 / 1e-4: {linear:.2f}")

    claims = Claims("planetary", args.out, source="own")
    claims.add("The tangent map of the Kepler step agrees with finite differences to 1e-8 "
               "relative for e from 0 to 0.99", "≤ 1e-8",
               f"worst {worst_fd:.1e} over e = {', '.join(map(str, eccentricities))} and "
               "steps 0.05, 1, 7 (beyond a period)", worst_fd <= 1e-8)
    claims.add("… and with the Taylor reference to round-off over one orbit",
               "round-off", f"tangent {tangent_err:.1e} of ‖J‖ = {norm_J:.0f} (ε‖J‖ = "
               f"{2.2e-16 * norm_J:.1e}); orbit {orbit_err:.1e}",
               max(tangent_err, orbit_err) <= 4 * 2.2e-16 * norm_J,
               note="the conditioning ‖J‖ of the map over the orbit bounds what round-off "
                    "can give, for the orbit as for the tangent: a rounding of one step's "
                    "state is carried to the end by the tangent map of the remaining steps")
    claims.add("The WH scheme's energy error scales as ε τ²", "slope 2, linear in ε",
               f"slopes {slopes['WH, eps=1e-3']:.2f} (ε = 1e-3), {slopes['WH, eps=1e-5']:.2f} "
               f"(ε = 1e-5); error ratio for ε = 1e-3 / 1e-4: {linear:.2f}",
               abs(slopes["WH, eps=1e-3"] - 2) < 0.1 and abs(linear - 10) < 1)
    claims.add("… and as ε τ⁴ + ε² τ² with the corrector", "slope 4 at small ε, 2 at large ε",
               f"slope {slopes['WH + corrector 3, eps=1e-5']:.2f} at ε = 1e-5 (T/24–T/48), "
               f"{slopes['WH + corrector 3, eps=1e-2']:.2f} at ε = 1e-2 (T/32–T/64), "
               f"{quadratic:.2f} decades from ε = 1e-3 to 1e-2 at T/48",
               abs(slopes["WH + corrector 3, eps=1e-5"] - 4) < 0.3
               and abs(slopes["WH + corrector 3, eps=1e-2"] - 2) < 0.2,
               note="the decade count exceeds the 2 of ε²τ² alone (ετ⁴ at ε = 1e-3 would "
                    "lower it): terms of higher order in ε weigh in at ε = 1e-2, not "
                    "analysed here; the slopes are the claim")
    claims.save()

    path, plt = figure(args.out, "planetary")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
    for label, style in (("WH", "-o"), ("WH + corrector 3", "-s"), ("SABA2", "-^"),
                         ("ABA1064", "-v")):
        for eps, alpha in ((1e-3, 1.0), (1e-5, 0.5)):
            axes[0].loglog(taus, errs(eps, label), style, alpha=alpha, ms=3,
                           label=f"{label}, ε = {eps:g}")
    axes[0].set_xlabel("τ")
    axes[0].set_ylabel("max relative energy error")
    axes[0].legend(fontsize=6, ncol=2)
    for h in (0.05, 1.0, 7.0):
        pts = [r for r in fd_rows if r["h"] == h]
        axes[1].semilogy([r["e"] for r in pts], [r["relative_error"] for r in pts], "-o", ms=3,
                         label=f"h = {h:g}")
    axes[1].axhline(1e-8, color="k", lw=0.8, ls="--")
    axes[1].set_xlabel("e")
    axes[1].set_ylabel("tangent map vs differences")
    axes[1].legend(fontsize=7)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    result["claims"] = claims.items
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)
