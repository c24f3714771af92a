"""How much one rounding grows on R1 and C2, and the round-off floor that
growth allows a double-precision integrator (issue 27, the floor targets
≤ 1e-13 at t = 1e3 and ≤ 1e-12 at t = 1e4).

The frontier's error (:mod:`studies.frontier`) is the larger relative
error of the final state x(t) and of one tangent vector w(t) = Φ(t) w₀.
Every step of an integrator that keeps its state in double rounds it;
each rounding then grows with the orbit's sensitivity, and no scheme or
step can make the sum of these grown roundings smaller than the
sensitivity allows. This study measures that sensitivity against a tight
reference and turns it into a floor.

Reference: heyoka's Taylor integrator (Biscani & Izzo 2021) in quadruple
precision (``heyoka.real128``, ε = 1.9e-34, tolerance ε) on the orbit and
its full tangent map Φ(s) (``var_ode_sys``), output every :data:`GRID`
time units to t = :data:`T_END`. Its own error (~1e-34 grown by the same
sensitivity) is 17 orders below the responses measured.

Responses of one rounding (one ulp: every non-zero component moved to its
neighbouring double, random signs; an ensemble of :data:`ENSEMBLE` sign
draws, its spread stored):

* state → state, ``xx``: ‖Φ(t) δx₀‖/‖x(t)‖ (linear: the perturbation stays
  ≤ 1e-8 relative; the quadruple runs below check it);
* vector → vector, ``ww``: ‖Φ(t) δw₀‖/‖Φ(t) w₀‖ (exact: w is linear);
* state → vector, ``xw``: the orbit and vector integrated again in
  quadruple precision from x₀ + δx₀ (:data:`QUAD_RUNS` of the draws),
  ‖w′(t) − w(t)‖/‖w(t)‖ — the tangent map's own dependence on the orbit.

Each is fitted a power law t^a over t = 10 … T_END (:func:`fit`): on a
2-torus (R1) a perturbation of the actions shears the angles, so ``xx``
and ``xw`` grow ∝ t and ``ww`` stays bounded (Φ(t) is a shear, w(t) ∝ t
and so is its perturbation). C2 is sticky until t ≈ 1e6 with χ₁ ≈ 4e-6
(Skokos & Gerlach 2010): over t ≤ 1e4 its growth is the sticky region's
power law, not e^{χ₁t} (χ₁t ≤ 0.04).

Floor model (:func:`model_floor`): an integrator whose state and vector
are double rounds every component at least once per step of τ, an error
uniform in ±ulp/2 (variance ulp²/12), independent between steps; each
grows linearly to t. The expected relative error at t is then

    F_x(t)² = Σ_n Σ_i ulp(x_i(t_n))²/12 · ‖Φ(t, t_n) e_i‖² / ‖x(t)‖²,
    Φ(t, s) = Φ(t) Φ(s)⁻¹,   Φ(s)⁻¹ = Jᵀ Φ(s)ᵀ J (Φ is symplectic),

summed over the steps t_n = nτ (on the grid, each point standing for
GRID/τ steps), and the vector's F_w from its own roundings the same way
plus the orbit's roundings through ``xw``, taken as stationary
(a rounding at s grows to t as one at 0 grows to t − s; checked on ``xx``
against the exact sum). The floor max(F_x, F_w) scales as τ^{−1/2}; it
is reported at τ = 1 (one rounding per time unit: fewer than any
integrator of the frontier makes) and at the steps of the schemes that
reach the stored floors. Compensated summation (``compensated=True``)
keeps the state's low bits and so is not bound by this model: its
remaining roundings are those of the increments (the forces from the
rounded position, the stage products), ulp(τ ẋ_i) instead of ulp(x_i),
a floor that falls as τ^{1/2} (``increment`` in :func:`model_floor`).
On R1 the compensated runs meet it within a factor of two; on C2 the
median of draws lies about ten times above it, which says the
stationary sum underestimates how a rounding late in the run moves C2's
vector (an assumption this study does not test on ``xw``).

Part ``floors`` (issue 27's push at C2, t = 1e3): the compensated TM
runs (``compensated=True`` and ``"step"``) of SRKN14a and s35odr10 over a
ladder of steps (:data:`LADDERS`), ``varint.integrate(model, x0, t,
tau=τ, scheme=s, deviations=w0, compensated=c)`` from R1 and C2 to
t = 1e3 and 1e4, their errors as in :mod:`studies.frontier` against the
quadruple-precision reference and against the long-double Taylor
reference the other studies use (:func:`varint.cache.reference`), whose
own error is measured on the way. A floor is one draw of a random sum of
roundings, so the minimum over the ladder is reported with the ladder's
errors at the other steps beside it, and C2's at t = 1e3 is drawn
:data:`DRAWS` times (n = N + 7k steps: the same truncation error, other
roundings) to give its median.

Usage: ``python studies/roundoff_conditioning.py [--quick] [--out DIR]
[--part conditioning|floors]`` (conditioning: two orbits to t = 1e4,
about 10 CPU minutes; floors: a few minutes after compiling;
``--quick``: t = 300 and 100)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.bench_peers import seeded_vectors  # noqa: E402
from studies.common import parse_args, save_json  # noqa: E402
from studies.frontier import relative  # noqa: E402
from varint import cachedir  # noqa: E402
from varint.cache import reference  # noqa: E402

ORBITS = ("R1", "C2")
#: Horizon (full, quick) and spacing of the reference's output grid.
T_END = (1e4, 300.0)
GRID = 1.0
#: Sign draws of the one-ulp perturbation (linear responses), and how many
#: of them are integrated again in quadruple precision (state → vector).
ENSEMBLE, QUAD_RUNS = 32, (2, 2)
SEED = 0
#: Times at which the floor is reported, and the fit's window start.
HORIZONS = (1e3, 1e4)
FIT_FROM = 10.0
#: Steps τ of the floor model: one rounding per time unit, and the steps
#: of the stored floors (s35odr10 τ = 0.2, SRKN14a τ = 1/32).
TAUS = (1.0, 0.2, 0.03125)


def quad_integrator(model, k):
    """heyoka in ``real128`` on the orbit and k columns of its tangent map
    (``var_ode_sys`` with respect to the first k initial conditions, whose
    columns are overwritten); row d + i·k + j is component i of column j."""
    import heyoka as hy
    from varint.baselines.taylor import heyoka_system

    fp = hy.real128
    system, variables = heyoka_system(model.symbolic(), fp)
    eqs = list(hy.var_ode_sys(system, variables[:k], order=1).sys) if k else system
    ta = hy.taylor_adaptive(eqs, [fp(0)] * len(eqs), fp_type=fp, compact_mode=True)
    return ta, fp


def to_longdouble(a, fp):
    """A ``real128`` array as long double: its leading double plus the
    double of the remainder (64 significant bits kept)."""
    hi = np.asarray(a).astype(np.float64)
    lo = (np.asarray(a) - hi.astype(fp)).astype(np.float64)
    return hi.astype(np.longdouble) + lo


def quad_run(model, x0, W0, grid):
    """x(s) and the columns W(s) = Φ(s) W₀ on ``grid`` in quadruple
    precision (``real128`` arrays), shapes (n, d) and (n, d, k), and the
    type."""
    d, k = model.dim, W0.shape[1]
    ta, fp = quad_integrator(model, k)
    state = np.array([fp(0)] * len(ta.state))
    state[:d] = [fp(float(v)) for v in x0]
    for i in range(d):
        for j in range(k):
            state[d + i * k + j] = fp(float(W0[i, j]))
    ta.state[:] = state
    ta.time = fp(0)
    out = ta.propagate_grid(np.array([fp(float(t)) for t in grid]))[-1]
    return out[:, :d], out[:, d:].reshape(len(grid), d, k), fp


def one_ulp(x, rng):
    """x with every non-zero component moved to its neighbouring double,
    the direction of each drawn from ``rng``."""
    x = np.asarray(x, dtype=float)
    towards = np.where(rng.random(x.size) < 0.5, -np.inf, np.inf)
    return np.where(x != 0.0, np.nextafter(x, towards), x)


def measured(name, t_end, quad_runs, fresh=False):
    """:func:`measure`, kept in varint's private cache directory
    (:func:`varint.cachedir.subdir`; 15 MB a run, re-made in minutes, so
    never stored with the results) so that the floors can be summed again."""
    folder = cachedir.subdir("studies")
    path = None if folder is None else (
        folder / f"conditioning-{name}-t{t_end:g}-grid{GRID:g}-q{quad_runs}.npz")
    if path is not None and path.exists() and not fresh:
        with np.load(path) as data:
            return dict(data)
    m = measure(name, t_end, quad_runs)
    if path is not None:
        np.savez(path, **m)
    return m


def measure(name, t_end, quad_runs):
    """The reference run of one orbit and the responses of one-ulp
    perturbations: a dict of long-double arrays on the grid."""
    model, x0 = varint.paper_orbit(name)
    x0 = np.asarray(x0, dtype=float)
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    grid = np.arange(0.0, t_end + GRID / 2, GRID)
    xq, Phiq, fp = quad_run(model, x0, np.eye(model.dim), grid)
    wq = sum(Phiq[:, :, j] * fp(float(v)) for j, v in enumerate(w0))
    x, Phi, w = to_longdouble(xq, fp), to_longdouble(Phiq, fp), to_longdouble(wq, fp)
    xdot, wdot = rates(model, x, w)
    rng = np.random.default_rng(SEED)
    dx = np.stack([one_ulp(x0, rng) - x0 for _ in range(ENSEMBLE)])
    dw = np.stack([one_ulp(w0, rng) - w0 for _ in range(ENSEMBLE)])
    norm_x, norm_w = np.linalg.norm(x, axis=1), np.linalg.norm(w, axis=1)
    xx = np.linalg.norm(Phi @ dx.T.astype(np.longdouble), axis=1) / norm_x[:, None]
    ww = np.linalg.norm(Phi @ dw.T.astype(np.longdouble), axis=1) / norm_w[:, None]
    xw, xx_quad = [], []
    for m in range(quad_runs):
        # Differences in quadruple precision, before rounding to long double.
        xp, wp, _ = quad_run(model, x0 + dx[m], w0[:, None], grid)
        xx_quad.append(np.linalg.norm(to_longdouble(xp - xq, fp), axis=1) / norm_x)
        xw.append(np.linalg.norm(to_longdouble(wp[:, :, 0] - wq, fp), axis=1) / norm_w)
    return {"t": grid, "x": x, "Phi": Phi, "w": w, "xdot": xdot, "wdot": wdot, "xx": xx.T, "ww": ww.T,
            "xw": np.array(xw), "xx_quad": np.array(xx_quad),
            "rel_dx0": np.linalg.norm(dx, axis=1) / np.linalg.norm(x0),
            "rel_dw0": np.linalg.norm(dw, axis=1) / np.linalg.norm(w0)}


def fit(t, y, lo=FIT_FROM):
    """Least-squares slope of log y against log t over t ≥ ``lo``, and its
    standard error."""
    keep = (t >= lo) & (y > 0)
    lt, ly = np.log(t[keep]), np.log(np.asarray(y[keep], dtype=float))
    A = np.vstack([lt, np.ones_like(lt)]).T
    coef, res, *_ = np.linalg.lstsq(A, ly, rcond=None)
    dof = max(len(lt) - 2, 1)
    cov = (float(res[0]) / dof if len(res) else 0.0) * np.linalg.inv(A.T @ A)
    return float(coef[0]), float(np.sqrt(cov[0, 0]))


def rms(a, axis=0):
    """Root mean square over the ensemble (``axis``), as float64."""
    return np.sqrt(np.mean(np.square(np.asarray(a, dtype=float)), axis=axis))


def spread_at(t, samples, at):
    """Min, median and max over the ensemble of the responses at time ``at``."""
    i = int(np.argmin(np.abs(t - at)))
    v = np.asarray(samples[:, i], dtype=float)
    return {"min": float(v.min()), "median": float(np.median(v)), "max": float(v.max()),
            "draws": int(v.size)}


def symplectic_inverse(Phi):
    """Φ⁻¹ = Jᵀ Φᵀ J for a stack of symplectic matrices (no division, so no
    loss where Φ is ill-conditioned)."""
    d = Phi.shape[-1] // 2
    J = np.zeros((2 * d, 2 * d), dtype=Phi.dtype)
    J[:d, d:], J[d:, :d] = np.eye(d), -np.eye(d)
    return J.T @ np.swapaxes(Phi, -1, -2) @ J


def rates(model, x, w):
    """ẋ = (M⁻¹p, −∇V(q)) and ẇ = (M⁻¹w_p, −D²V(q) w_q) on the grid
    (float64: they only set the size of a step's increments)."""
    d = model.dim // 2
    x, w = np.asarray(x, dtype=float), np.asarray(w, dtype=float)
    mass = np.asarray(model.inverse_mass, dtype=float)
    xdot = np.array([np.concatenate([mass * xi[d:], -model.gradient(xi[:d])]) for xi in x])
    wdot = np.array([np.concatenate([mass * wi[d:], -model.hessian(xi[:d]) @ wi[:d]])
                     for xi, wi in zip(x, w, strict=True)])
    return xdot, wdot


def model_floor(m, t_at, tau):
    """The floor model at ``t_at`` for steps τ (module docstring).

    Two per-step roundings: of the state (``plain``: ulp(x_i), what any
    integrator storing its state in double makes) and of the step's
    increment only (``increment``: ulp(τ ẋ_i), the bound of compensated
    summation, whose state keeps its low bits). F_x is the exact sum over
    the grid; F_w's own part is exact, its part from the orbit's roundings
    is the stationary sum of the ensemble's ``xw`` (scaled, for
    ``increment``, by the ratio of the two exact F_x).

    Returns
    -------
    dict
        Relative errors: ``plain`` and ``increment``, each with F_x, F_w
        (own, from the orbit) and the floor max(F_x, F_w); and F_x's
        stationary sum (a check on the stationarity F_w relies on).
    """
    t, i = m["t"], int(np.argmin(np.abs(m["t"] - t_at)))
    steps = GRID / tau                      # steps each grid point stands for
    Phi_ts = m["Phi"][i] @ symplectic_inverse(m["Phi"][:i])   # Φ(t, s_j), s_j < t
    col = np.linalg.norm(np.asarray(Phi_ts, dtype=float), axis=1) ** 2   # ‖Φ(t, s) e_i‖²
    norm_x, norm_w = float(np.linalg.norm(m["x"][i])), float(np.linalg.norm(m["w"][i]))

    def grown(size, norm):
        # √(Σ_n Σ_i ulp(size_i)²/12 ‖Φ(t, t_n) e_i‖²) / norm over the grid.
        ulp2 = np.spacing(np.abs(np.asarray(size[:i], dtype=float))) ** 2 / 12
        return float(np.sqrt(steps * np.sum(col * ulp2))) / norm

    # A rounding at s_j grows by the response at t − s_j; one ulp in every
    # component is √12 times one rounding's rms.
    lag = i - np.arange(i)
    xx_st = float(np.sqrt(steps * np.sum(rms(m["xx"])[lag] ** 2) / 12))
    xw_st = float(np.sqrt(steps * np.sum(rms(m["xw"])[lag] ** 2) / 12))
    out = {"t": float(t[i]), "tau": tau, "F_x_stationary": xx_st}
    sizes = {"plain": (m["x"], m["w"]), "increment": (tau * m["xdot"], tau * m["wdot"])}
    f_x_plain = grown(m["x"], norm_x)
    for kind, (sx, sw) in sizes.items():
        f_x, own_w = grown(sx, norm_x), grown(sw, norm_w)
        from_orbit = xw_st * f_x / f_x_plain
        f_w = float(np.hypot(own_w, from_orbit))
        out[kind] = {"F_x": f_x, "F_w_own": own_w, "F_w_from_orbit": from_orbit, "F_w": f_w,
                     "floor": max(f_x, f_w)}
    return out


def summarise(name, m, quick):
    t = m["t"]
    laws = {k: dict(zip(("exponent", "stderr"), fit(t, rms(m[k])), strict=True))
            for k in ("xx", "ww", "xw")}
    horizons = [h for h in HORIZONS if h <= t[-1]] or [float(t[-1])]
    at = {f"{h:g}": {k: spread_at(t, m[k], h) for k in ("xx", "ww", "xw", "xx_quad")}
          for h in horizons}
    # Linearity: the quadruple runs' state response against Φ δx₀.
    lin = float(np.max(np.abs(m["xx_quad"][:, 1:] / m["xx"][:len(m["xx_quad"]), 1:] - 1)))
    floors = [model_floor(m, h, tau) for h in horizons for tau in TAUS]
    curve_t = np.unique(np.geomspace(GRID, t[-1], 25).round())
    return {"orbit": name, "t_end": float(t[-1]), "grid": GRID, "quick": quick,
            "relative_perturbation": {"state": float(np.median(m["rel_dx0"])),
                                      "vector": float(np.median(m["rel_dw0"]))},
            "laws": laws, "responses": at, "linearity": lin, "floors": floors,
            "curve": {"t": curve_t, **{k: rms(m[k])[np.searchsorted(t, curve_t)]
                                       for k in ("xx", "ww", "xw")}}}


#: Part floors: compensation levels, schemes and steps, and the cases.
LEVELS = (True, "step")
LADDERS = ({"SRKN14a": (1 / 16, 1 / 24, 1 / 32, 1 / 48, 1 / 64, 1 / 96, 1 / 128, 1 / 192,
                         1 / 256),
            "s35odr10": (0.2, 0.16, 0.125, 0.1, 0.08, 0.0625)},
           {"SRKN14a": (1 / 16, 1 / 32), "s35odr10": (0.2,)})
FLOOR_CASES = ((("R1", 1e3), ("R1", 1e4), ("C2", 1e3), ("C2", 1e4)), (("C2", 100.0),))
TARGETS = {1e3: 1e-13, 1e4: 1e-12}
#: Draws of one floor: C2 to t = 1e3 with SRKN14a+c at n = N + 7k steps
#: (k = 0 … DRAWS − 1): the same truncation error within 0.1 %, other
#: roundings; (full, quick).
DRAW_CASE = (("C2", 1e3, "SRKN14a", (32_000, 128_000)), ("C2", 100.0, "SRKN14a", (3_200,)))
DRAWS = 12


def floor_draws(m, name, t_end, scheme, base_steps):
    """The error of ``draws`` runs at n = N + 7k steps for each N in
    ``base_steps`` (full compensation), against the quadruple reference:
    the spread of one floor over roundings alone."""
    model, x0 = varint.paper_orbit(name)
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    i = int(np.argmin(np.abs(m["t"] - t_end)))
    out = []
    for n0 in base_steps:
        errors = []
        for k in range(DRAWS):
            r = varint.integrate(model, x0, t_end, tau=t_end / (n0 + 7 * k), scheme=scheme,
                                 deviations=w0[:, None], compensated=True)
            errors.append(max(relative(r.state, m["x"][i]),
                              relative(r.deviations[:, 0], m["w"][i])))
        out.append({"orbit": name, "t_end": t_end, "scheme": f"{scheme}+c", "steps": n0,
                    "tau": t_end / n0, "errors": errors, "median": float(np.median(errors)),
                    "min": min(errors), "max": max(errors),
                    "model_increment": model_floor(m, t_end, t_end / n0)["increment"]["floor"]})
    return out


def floor_case(m, name, t_end, ladders):
    """The rows of one (orbit, horizon): every level, scheme and step, its
    errors against both references (the quadruple one from the
    conditioning part's run ``m``), and the long-double reference's own."""
    model, x0 = varint.paper_orbit(name)
    w0 = seeded_vectors(model.dim, 1, 1, seed=0)[0][:, 0]
    i = int(np.argmin(np.abs(m["t"] - t_end)))
    x_ref, w_ref = m["x"][i], m["w"][i]
    ext = reference(model, x0, t_end, tau=0.1, deviations=w0[:, None])
    ext_error = max(relative(ext.state, x_ref), relative(ext.deviations[:, 0], w_ref))
    rows = []
    for scheme, taus in ladders.items():
        for tau in taus:
            for level in LEVELS:
                r = varint.integrate(model, x0, t_end, tau=tau, scheme=scheme,
                                     deviations=w0[:, None], compensated=level)
                x, w = r.state, r.deviations[:, 0]
                rows.append({"orbit": name, "t_end": t_end, "scheme": scheme, "tau": tau,
                             "level": {True: "+c", "step": "+cs"}[level],
                             "error": max(relative(x, x_ref), relative(w, w_ref)),
                             "error_state": relative(x, x_ref),
                             "error_vector": relative(w, w_ref),
                             "error_vs_extended": max(relative(x, ext.state),
                                                      relative(w, ext.deviations[:, 0]))})
    return rows, ext_error


def floors_part(args):
    rows, cases = [], []
    for name, t_end in FLOOR_CASES[args.quick]:
        m = measured(name, T_END[args.quick], QUAD_RUNS[args.quick])
        mine, ext_error = floor_case(m, name, t_end, LADDERS[args.quick])
        rows += mine
        best = min(mine, key=lambda r: r["error"])
        ladder = [(r["tau"], r["error"]) for r in mine
                  if (r["scheme"], r["level"]) == (best["scheme"], best["level"])]
        target = TARGETS.get(t_end)
        # The models at the best run's step.
        model = model_floor(m, t_end, best["tau"])
        cases.append({"orbit": name, "t_end": t_end, "floor": best["error"],
                      "model_increment": model["increment"]["floor"],
                      "model_plain": model["plain"]["floor"],
                      "at": f"{best['scheme']}{best['level']} tau={best['tau']:g}",
                      "ladder": ladder,
                      "floor_vs_extended": min(r["error_vs_extended"] for r in mine),
                      "extended_reference_error": ext_error, "target": target,
                      "met": None if target is None or args.quick else best["error"] <= target})
        print(f"{name} t = {t_end:g}: floor {best['error']:.2e} ({cases[-1]['at']}; its "
              f"ladder " + ", ".join(f"{e:.1e}" for _, e in ladder) + "); against the long-double "
              f"reference {cases[-1]['floor_vs_extended']:.2e}, whose own error is "
              f"{ext_error:.2e}; model at its step: compensated "
              f"{cases[-1]['model_increment']:.2e}, plain {cases[-1]['model_plain']:.2e}",
              flush=True)
    for r in rows:
        print(f"  {r['orbit']} t={r['t_end']:g} {r['scheme']}{r['level']} tau={r['tau']:.5g}: "
              f"{r['error']:.2e} (state {r['error_state']:.2e}, vector "
              f"{r['error_vector']:.2e}; vs long double {r['error_vs_extended']:.2e})")
    name, t_end, scheme, base = DRAW_CASE[args.quick]
    draws = floor_draws(measured(name, T_END[args.quick], QUAD_RUNS[args.quick]), name, t_end,
                        scheme, base)
    for d in draws:
        print(f"{name} t = {t_end:g} {d['scheme']} n ≈ {d['steps']} (τ ≈ {d['tau']:.3g}), "
              f"{DRAWS} draws: median {d['median']:.2e} ({d['min']:.1e} – {d['max']:.1e}); "
              f"model {d['model_increment']:.2e}")
    save_json(args.out, "roundoff_conditioning_floors",
              {"rows": rows, "cases": cases, "draws": draws, "quick": args.quick},
              times="no time measured: errors against the quadruple-precision reference")
    return {"rows": rows, "cases": cases}


def options(parser):
    parser.add_argument("--part", choices=("conditioning", "floors"), default="conditioning")
    parser.add_argument("--fresh", action="store_true",
                        help="measure again instead of reading out/runs")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=options)
    if args.part == "floors":
        return floors_part(args)
    t_end, quad_runs = T_END[args.quick], QUAD_RUNS[args.quick]
    result = {"orbits": {}, "taus": TAUS, "ensemble": ENSEMBLE, "quad_runs": quad_runs,
              "seed": SEED}
    for name in ORBITS:
        m = measured(name, t_end, quad_runs, args.fresh)
        s = summarise(name, m, args.quick)
        result["orbits"][name] = s
        print(f"{name}: one ulp = {s['relative_perturbation']['state']:.2e} (state), "
              f"{s['relative_perturbation']['vector']:.2e} (vector) relative; linearity "
              f"{s['linearity']:.1e}", flush=True)
        for k, law in s["laws"].items():
            print(f"  {k}: response ∝ t^{law['exponent']:.2f} ± {law['stderr']:.2f}")
        for h, r in s["responses"].items():
            print(f"  t = {h}: " + ", ".join(f"{k} {v['median']:.2e} ({v['min']:.1e}–"
                                             f"{v['max']:.1e})" for k, v in r.items()))
        for f in s["floors"]:
            for kind in ("plain", "increment"):
                g = f[kind]
                print(f"  floor model t = {f['t']:g}, τ = {f['tau']:g}, {kind:9s}: F_x "
                      f"{g['F_x']:.2e}, F_w {g['F_w']:.2e} (own {g['F_w_own']:.2e}, orbit "
                      f"{g['F_w_from_orbit']:.2e}) → {g['floor']:.2e}")
            print(f"    (F_x plain, stationary sum: {f['F_x_stationary']:.2e})")
    save_json(args.out, "roundoff_conditioning", result,
              times="no time measured: responses and floors from quadruple-precision runs")
    return result


if __name__ == "__main__":
    main()
