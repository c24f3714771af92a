"""Held-out Hamiltonians: general H(q, p) that are in no model, test or
study of the repository, built by ``varint.models.from_hamiltonian`` from
one SymPy expression and raced against heyoka (issue 29: "some checks of
this issue use Hamiltonians kept outside the repository on purpose").

Systems (bounded motion at the chosen states; every parameter a number):

``relativistic``
    A relativistic particle in a two-dimensional anharmonic well,
    H = √(1 + |p|²) + V(q), V = ½|q|² + ¼q₁⁴ + ½q₁²q₂²: T(p) + V(q), so
    ``from_hamiltonian`` should recognise "separable" and integrate it by
    the explicit splittings with the exact flow of T (Forest & Ruth 1990,
    with the drift q ← q + h∇T(p)).
``position-dependent mass``
    H = ½(1 + q₁² + q₂²)|p|² + V(q) (the same V): a kinetic term whose
    metric depends on q, as in the geodesic flows of a conformal metric;
    no split keeps it explicit, so "general" (Gauss–Legendre by default).
``angular coupling``
    H = ½|p|² + V_HH(q) + ε(q₁p₂ − q₂p₁)², ε = 1/10, V_HH Hénon–Heiles'
    potential (Hénon & Heiles 1964): the square of the angular momentum
    couples every coordinate with the other's momentum; "general".
``three dof``
    H = ½|p|² + ½|q|² + ½(q₁²q₂² + q₂²q₃² + q₃²q₁²) + ε(q·p)²/2, ε = 1/5:
    three degrees of freedom coupled through the square of the virial
    q·p; "general".

For each system the study records the structure recognised and the
scheme the model defaults to (and that both are what its form asks), then

1. **the tangent map against finite differences of the flow**: the default
   scheme's numerical flow over t = 5 at τ = 0.05 with the full tangent map
   M (``varint.integrate`` with the identity as deviations), against
   central differences (x(x₀ + εe_j) − x(x₀ − εe_j))/2ε, ε = 1e-5, of the
   same numerical flow (truncation O(ε²) and round-off O(u/ε): both far
   below the bound 1e-6 relative to max|M|); and the symplecticity
   max|MᵀJM − J| of the same M;
2. **the race**: orbit and one tangent vector
   (``studies.hamiltonians``'s precision machinery, imported: its error is
   the larger of the orbit's max-norm error and of the accumulated
   log-stretching's, against heyoka's Taylor method in extended precision
   at tol ε, t = 100; cost is wall time on one thread, every knob compiled
   first, interleaved, minimum of the repeats) of varint's defaults (τ
   chosen by varint), its schemes at a ladder of steps (Gauss–Legendre
   GL4/GL6/GL8 and Tao's TAO4 for the general ones; the explicit
   splittings, s15odr8 among them, for the separable one; steps from
   τ = 0.8 for GL8 and 0.4 or 0.5 for the other high orders, so that no
   front is capped by its largest step), heyoka's Taylor method from the same
   expression at tolerances 1e-4 … 1e-12 and DOP853. The ratio is
   heyoka's cost over varint's at errors 1e-6 and 1e-8, both read off their
   cost–error fronts (log–log interpolated; "at most" when a front's
   cheapest point is already that accurate), and, as the precision part
   reports it, the smallest heyoka/varint ratio over each method's own
   points with errors ≥ 1e-8. Target of issue 29: ≥ 0.5 (within 2×).

Usage: ``python studies/general_h_heldout.py [--quick] [--out DIR]
[--repeats N]``; results in ``general_h_heldout.json``/``.csv`` and the
claims in ``general_h_heldout.claims.json``. State the load (recorded).
"""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import sympy as sp

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.claims import cost_at
from studies.common import Claims, parse_args, save_csv, save_json
from studies.hamiltonians import contender_fronts, load, precision_case
from varint.models import from_hamiltonian

REPEATS = 3
#: The error levels of the race (issue 29: errors ≥ 1e-8).
LEVELS = (1e-6, 1e-8)
#: heyoka's tolerances: loose enough that its front reaches errors 1e-6.
HEYOKA_TOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-10, 1e-12)
#: The finite-difference check: horizon, step, half-width and bound.
FD_T, FD_TAU, FD_EPS, FD_BOUND = 5.0, 0.05, 1e-5, 1e-6
#: Steps of each varint scheme. A ladder capped at τ = 0.2 made GL8's
#: cheapest point 100× more accurate than 1e-8 (3.5e-11 to 3e-10 at
#: τ = 0.2): the high orders start at τ = 0.8 (GL8) and 0.4, with steps in
#: between (100/τ an integer) where their fronts cross 1e-8 and 1e-6, as
#: heyoka's tolerances span 1e-4 … 1e-12. Tao's at half of GL4's (its step
#: costs about half a GL4 step).
GENERAL_TAUS = {"GL4": (0.2, 0.1, 0.05, 0.025),
                "GL6": (0.4, 0.25, 0.2, 0.1, 0.05),
                "GL8": (0.8, 0.5, 0.4, 0.3125, 0.25, 0.2, 0.1),
                "TAO4": (0.1, 0.05, 0.025, 0.0125)}
#: Steps of the explicit splittings of a separable H; s15odr8 (order 8 for
#: any T(p) + V(q)) at longer ones.
SEPARABLE_TAUS = {"s11odr6": (0.4, 0.25, 0.2, 0.125, 0.1, 0.05),
                  "SRKN14a": (0.4, 0.2, 0.1, 0.05),
                  "ABA864": (0.4, 0.2, 0.1, 0.05),
                  "s15odr8": (0.5, 0.4, 0.25, 0.2, 0.125, 0.1)}


def heldout():
    """name → (H, q, p, x0, expected structure): the held-out systems
    (module docstring)."""
    q1, q2, q3, p1, p2, p3 = sp.symbols("q1 q2 q3 p1 p2 p3")
    well = (q1 ** 2 + q2 ** 2) / 2 + q1 ** 4 / 4 + q1 ** 2 * q2 ** 2 / 2
    henon_heiles = (q1 ** 2 + q2 ** 2) / 2 + q1 ** 2 * q2 - q2 ** 3 / 3
    return {
        "relativistic": (sp.sqrt(1 + p1 ** 2 + p2 ** 2) + well, (q1, q2), (p1, p2),
                         (0.3, 0.2, 0.4, 0.3), "separable"),
        "position-dependent mass": ((1 + q1 ** 2 + q2 ** 2) * (p1 ** 2 + p2 ** 2) / 2 + well,
                                    (q1, q2), (p1, p2), (0.3, 0.2, 0.4, 0.3), "general"),
        "angular coupling": ((p1 ** 2 + p2 ** 2) / 2 + henon_heiles
                             + sp.Rational(1, 10) * (q1 * p2 - q2 * p1) ** 2,
                             (q1, q2), (p1, p2), (0.1, 0.05, 0.2, 0.25), "general"),
        "three dof": ((p1 ** 2 + p2 ** 2 + p3 ** 2) / 2 + (q1 ** 2 + q2 ** 2 + q3 ** 2) / 2
                      + (q1 ** 2 * q2 ** 2 + q2 ** 2 * q3 ** 2 + q3 ** 2 * q1 ** 2) / 2
                      + sp.Rational(1, 5) * (q1 * p1 + q2 * p2 + q3 * p3) ** 2 / 2,
                      (q1, q2, q3), (p1, p2, p3), (0.3, 0.2, 0.1, 0.2, 0.3, 0.4), "general"),
    }


def build(name, H, q, p):
    """The model ``from_hamiltonian`` makes of H, its structure ("potential"
    for a ``from_potential`` model) and default scheme."""
    model = from_hamiltonian(H, q, p, name=name)
    return model, getattr(model, "structure", "potential"), model.default_scheme


def contenders(model, structure):
    """The precision part's contenders (label, method, options, knobs,
    model) of varint on ``model``: its defaults (scheme and τ chosen by
    varint for the default energy tolerance, the pilot included in its
    cost) and its schemes at a ladder of steps."""
    out = [("varint defaults", "tm", {"energy_tol": None}, (None,), model)]
    ladder = GENERAL_TAUS if structure == "general" else SEPARABLE_TAUS
    for scheme, taus in ladder.items():
        out.append((scheme, "tm", {"scheme": scheme}, taus, model))
    return out


def peers(model):
    """heyoka's Taylor method from the same expression, and DOP853."""
    return [("heyoka", "taylor", {}, HEYOKA_TOLS, model),
            ("DOP853", "dop853", {}, (1e-6, 1e-8, 1e-10, 1e-12), model)]


def finite_difference_check(model, x0):
    """The default scheme's tangent map over :data:`FD_T` against central
    differences of its own flow, and its symplecticity (module docstring)."""
    d = model.dim
    run = dict(tau=FD_TAU, t_out=[FD_T], energy_tol=math.inf, progress=False)
    tangent = varint.integrate(model, x0, FD_T, deviations=np.eye(d), **run).deviations
    fd = np.empty((d, d))
    for j in range(d):
        ends = [varint.integrate(model, x0 + s * FD_EPS * np.eye(d)[j], FD_T, **run).state
                for s in (1.0, -1.0)]
        fd[:, j] = (ends[0] - ends[1]) / (2 * FD_EPS)
    n = d // 2
    J = np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])
    scale = float(np.abs(tangent).max())
    return {"fd_relative": float(np.abs(tangent - fd).max()) / scale,
            "symplecticity": float(np.abs(tangent.T @ J @ tangent - J).max()),
            "tangent_scale": scale, "fd_ok": float(np.abs(tangent - fd).max()) / scale
            < FD_BOUND}


def ratios_at(rows, levels=LEVELS):
    """heyoka's cost over each varint contender's at each error of
    ``levels``, both read off their fronts: label → {level: (ratio, how
    varint's cost was read, how heyoka's was)}; None where a front does
    not reach the level."""
    fronts, heyoka = contender_fronts(rows)
    out = {}
    for label, front in fronts.items():
        if label in ("heyoka", "DOP853"):
            continue
        out[label] = {}
        for level in levels:
            ours, how_ours = cost_at(front, level)
            theirs, how_theirs = cost_at(heyoka, level)
            out[label][level] = (None if ours is None or theirs is None else theirs / ours,
                                 how_ours, how_theirs)
    return out


def run(quick, repeats):
    """Every held-out system: structure, finite-difference check and race
    (rows, per-system summary)."""
    checks, systems = {}, {}
    t_end = 20.0 if quick else 100.0
    for name, (H, q, p, x0, expected) in heldout().items():
        model, structure, scheme = build(name, H, q, p)
        x0 = np.array(x0, dtype=float)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            checks[name] = {"H": str(H), "structure": structure, "expected": expected,
                            "default_scheme": scheme, **finite_difference_check(model, x0)}
        print(name, checks[name], flush=True)
        systems[name] = (model, x0, t_end, contenders(model, structure))
    rows, methods = precision_case(quick, repeats, systems=systems, peers=peers)
    summary = {}
    for name in systems:
        mine = [r for r in rows if r["system"] == name]
        defaults = next(r for r in mine if r["contender"] == "varint defaults")
        summary[name] = {"methods": methods[name], "at_levels": ratios_at(mine),
                         "defaults": {"seconds": defaults["seconds"], "error": defaults["error"]}}
    return checks, rows, summary


def verdict(summary):
    """The best varint method at each level and its ratio (the target asks
    ≥ 0.5 at each of :data:`LEVELS`), and, as the precision part reports
    it, the method whose smallest ratio over its own points ≥ 1e-8 is
    largest. ``summary`` as :func:`run` makes it or as its JSON stores it
    (levels as text)."""
    out = {}
    for level in LEVELS:
        at = {k: v[level] if level in v else v[str(level)]
              for k, v in summary["at_levels"].items()}
        found = {k: v[0] for k, v in at.items() if v[0] is not None}
        best = max(found, key=found.get) if found else None
        out[level] = (best, found.get(best))
    worst = {k: v["worst"] for k, v in summary["methods"].items() if v["worst"] is not None}
    out["worst"] = max(worst.items(), key=lambda kv: kv[1]) if worst else (None, None)
    return out


def table(checks, summary):
    lines = [f"{'system':<24} {'structure':<10} {'default':<8} {'FD rel':>8} {'MᵀJM−J':>8} "
             + " ".join(f"{'best @ ' + format(lv, 'g'):>22}" for lv in LEVELS)
             + f" {'worst ≥ 1e-8 (best)':>24}"]
    for name, c in checks.items():
        v = verdict(summary[name])
        cells = [f"{(v[lv][0] or '-') + ' ' + (format(v[lv][1], '.2f') if v[lv][1] else ''):>22}"
                 for lv in LEVELS]
        w = v["worst"]
        lines.append(f"{name:<24} {c['structure']:<10} {c['default_scheme']:<8} "
                     f"{c['fd_relative']:>8.1e} {c['symplecticity']:>8.1e} " + " ".join(cells)
                     + f" {(w[0] or '-') + ' ' + (format(w[1], '.2f') if w[1] else ''):>24}")
    return "\n".join(lines)


def claims(out, checks, summary, start):
    c = Claims("general_h_heldout", out, source="own")
    for name, check in checks.items():
        c.add(f"Held-out H '{name}': from_hamiltonian recognises {check['expected']}",
              paper=check["expected"], ours=f"{check['structure']}, default "
              f"{check['default_scheme']}", holds=check["structure"] == check["expected"])
        c.add(f"Held-out H '{name}': tangent map = finite differences of the flow "
              f"(relative ≤ {FD_BOUND:g})", paper=f"≤ {FD_BOUND:g}",
              ours=f"{check['fd_relative']:.1e}; MᵀJM − J: {check['symplecticity']:.1e}",
              holds=check["fd_ok"])
        v = verdict(summary[name])
        worst_label, worst = v["worst"]
        ratios = [v[level][1] for level in LEVELS]
        met = all(r is not None and r >= 0.5 for r in ratios)
        c.add(f"Held-out H '{name}': orbit + tangent within 2× of heyoka at equal accuracy "
              "at errors 1e-6 and 1e-8 (issue 29: errors ≥ 1e-8)", paper="heyoka/varint ≥ 0.5",
              ours="; ".join(f"at {level:g}: {v[level][0]} {v[level][1]:.3g}" if v[level][1]
                             else f"{level:g} not reached" for level in LEVELS)
              + (f"; smallest over {worst_label}'s points ≥ 1e-8: {worst:.3g}" if worst
                 else "") + f"; load {start[0]:.1f}",
              holds=met, note="" if met else (
                  "heyoka's Taylor steps are long on these small smooth systems; an implicit "
                  "Gauss–Legendre step costs its fixed-point iterations (several evaluations "
                  "of ∇H per stage) and the steps of the ladder start at τ = 0.2"))
    c.save()


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=REPEATS)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    start = load()
    checks, rows, summary = run(args.quick, args.repeats)
    result = {"quick": args.quick, "checks": checks, "rows": rows, "summary": summary,
              "load": start, "load_end": load()}
    save_csv(args.out, "general_h_heldout", rows,
             ["system", "contender", "knob", "seconds", "error", "t_end"])
    save_json(args.out, "general_h_heldout", result)
    claims(args.out, checks, summary, start)
    print(table(checks, summary))
    print(f"load {start} → {result['load_end']}")
    return result


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
