"""The cost of one force + Hessian evaluation of the Ferrers bar (issue 29):
varint's compiled ``ferrers_grad_hess`` and the bar model's whole
``grad_hess_v`` against AGAMA's ``Potential.eval(..., acc=True, der=True)`` (its
force and force derivatives, what ``forceDeriv`` computed).

Case
----
Three sets of positions (seed 20): ``inside`` (uniform in the bar's
ellipsoid, a, b, c = 6, 1.5, 0.6: λ = 0, the W tables are constants),
``outside`` (uniform in |x| < 8, |y| < 4, |z| < 1.5 outside the ellipsoid:
λ is a root and the W_ijk elliptic integrals, every call) and ``orbits``
(the positions of the named orbits :data:`varint.models.bar.BAR_ORBITS`
every 0.2 up to t = 100, as varint's runs see them: the regular orbit stays
inside the bar, the chaotic one 73 % inside).

Method
------
varint: a compiled loop over the positions calls the function (its
gradient and Hessian added to accumulators, so nothing is optimised away);
``ferrers_grad_hess`` is the bar alone with its potential, ``ferrers_kick``
the same without the potential (where the code has it), ``model`` the bar
model's ``grad_hess_v`` (Miyamoto–Nagai disc + Plummer bulge + bar, what
the part flows' kick evaluates), ``model extra_force`` the kernel a
generated stepper's kick calls (bar25: disc, bulge and bar,
:func:`varint.models.bar.galaxy_force`; before, the bar alone, the disc
and bulge written into the stepper from SymPy). AGAMA: ``eval`` of the Ferrers
potential alone, and of the whole model, on the (M, 3) array of positions
at once (its C++ loop; ``agama`` 1.0.159 built from source, one thread)
and on one position per call (the per-call cost its orbit integrator does
not pay, shown for scale). Seconds per evaluation: the minimum over
``--repeats`` interleaved turns (:func:`studies.common.interleaved`) of
one call's time over the set's size, wall time or (``--clock cpu``) the
process's CPU time. The load of the shared machine is stored with them.

The defaults on one orbit (issue 29's "the pilots cost 4–7× the run"):
``lyapunov_spectrum(model, x0, 100, deviations=w0, t_out=[100])`` with no
step given, per named orbit, ``--repeats`` times after a warm call; kept
(``defaults`` in the JSON): the minimum of the call's own ``timing``
(``pilot``, ``run``: :class:`varint.Provenance`), the step chosen and the
pilots' rungs tried and steps (``tau_choice``) against the run's steps.

Stored as ``bar_force_cost_<label>.json``/``.csv`` under ``--out``
(``studies/results/bar20`` by default); ``--label`` names the code
measured (``before``: main 4f2bb83 on ``PYTHONPATH``, ``after``: this
branch).

``--baseline DIR`` also times the ``ferrers_kick`` of the code in DIR (its
``varint/models/ferrers.py`` loaded beside this one, ``baseline
ferrers_kick``), interleaved with this code's in the same process: the
ratio of the two is the load's least noisy measure of a change to it.

Usage: ``python studies/bar_force_cost.py [--quick] [--label L] [--repeats N]
[--baseline DIR] [--clock wall|cpu]``.
"""

from __future__ import annotations

import importlib.util
import inspect
import os
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import varint
from studies.common import RESULTS, interleaved, parse_args, save_csv, save_json
from varint.models.bar import BAR_ORBITS, SPA02, RotatingBar, bar_orbit
from varint.models.ferrers import ferrers_grad_hess

COLUMNS = ["points", "contender", "count", "ns_per_eval"]


@njit(cache=True, error_model="numpy")
def _ferrers_loop(Q, axes2, gm, inside):
    """Σ of the gradient and Hessian of the bar at every row of ``Q``."""
    g = np.zeros(3)
    D = np.zeros((3, 3))
    for m in range(Q.shape[0]):
        ferrers_grad_hess(Q[m], axes2, gm, g, D, True, inside)
    return g.sum() + D.sum()


def _kick_loop(module=None):
    """:func:`_ferrers_loop` of ``ferrers_kick`` (no Φ: what the model's
    kick calls) of ``module`` (default varint's), or None in code that has
    none (main 4f2bb83)."""
    if module is None:
        from varint.models import ferrers as module
    ferrers_kick = getattr(module, "ferrers_kick", None)
    if ferrers_kick is None:
        return None

    @njit(error_model="numpy")
    def loop(Q, axes2, gm, inside):
        g = np.zeros(3)
        D = np.zeros((3, 3))
        for m in range(Q.shape[0]):
            ferrers_kick(Q[m], axes2, gm, g, D, True, inside)
        return g.sum() + D.sum()
    return loop


def _model_loop(grad_hess):
    """A compiled loop over positions of a model's ``grad_hess_v``."""
    @njit(error_model="numpy")
    def loop(Q, par):
        g = np.zeros(3)
        D = np.zeros((3, 3))
        total = 0.0
        for m in range(Q.shape[0]):
            grad_hess(Q[m], par, g, D)
            total += g[0] + D[0, 0]
        return total
    return loop


def _extra_loop(force):
    """A compiled loop over positions of a model's extra force (the
    generated stepper's kick adds it to its closed part), with its
    constants as the stepper passes them (tuples as arrays; written out as
    the stepper writes them: numba inlines no call with ``*args``)."""
    constants = tuple(np.array(c) if isinstance(c, tuple) else float(c)
                      for c in force.constants)
    names = ", ".join(f"c{i}" for i in range(len(constants)))
    namespace = {"np": np, "function": force.function}
    exec(f"def loop(Q, {names}):\n"
         "    g = np.zeros(3)\n"
         "    D = np.zeros((3, 3))\n"
         "    for m in range(Q.shape[0]):\n"
         f"        function(Q[m], g, D, True, {names})\n"
         "    return g.sum() + D.sum()\n", namespace)
    loop = njit(error_model="numpy")(namespace["loop"])
    return lambda Q: loop(Q, *constants)


def positions(quick):
    """name → (M, 3) positions (module docstring)."""
    rng = np.random.default_rng(20)
    axes = np.array(SPA02["axes"])
    count = 200 if quick else 2000
    u = rng.uniform(-1.0, 1.0, size=(8 * count, 3))
    inside = (u[(u * u).sum(1) < 1.0][:count] * axes)
    box = rng.uniform(-1.0, 1.0, size=(8 * count, 3)) * np.array([8.0, 4.0, 1.5])
    outside = box[((box / axes) ** 2).sum(1) > 1.0][:count]
    orbit = []
    for name in BAR_ORBITS:
        model, x0 = bar_orbit(name)
        run = varint.integrate(model, x0, 100.0, tau=0.2, scheme="SRKN14a",
                               t_out=np.linspace(0.2, 100.0, 500))
        orbit.append(np.asarray(run.states)[:, :3])
    return {"inside": np.ascontiguousarray(inside), "outside": np.ascontiguousarray(outside),
            "orbits": np.ascontiguousarray(np.concatenate(orbit))}


def _agama():
    """AGAMA's bar alone and whole model, or None where it does not import."""
    try:
        import agama
    except ImportError:
        return None
    agama.setNumThreads(1)
    a, b, c = SPA02["axes"]
    bar = {"type": "Ferrers", "mass": SPA02["bar_mass"], "scaleRadius": a,
           "axisRatioY": b / a, "axisRatioZ": c / a}
    whole = agama.Potential(
        {"type": "MiyamotoNagai", "mass": SPA02["disc_mass"], "scaleRadius": SPA02["disc_a"],
         "scaleHeight": SPA02["disc_b"]},
        {"type": "Plummer", "mass": SPA02["bulge_mass"], "scaleRadius": SPA02["bulge_radius"]},
        bar)
    return agama.Potential(bar), whole


def _baseline_kick(code_dir, axes2, gm):
    """(the kick loop, its inside table) of the Ferrers module of the code
    in ``code_dir`` (a self-contained module: math, NumPy, numba), loaded
    beside this code's under another name, so both are timed in one run,
    interleaved; None without ``code_dir``."""
    if code_dir is None:
        return None
    path = Path(code_dir) / "varint" / "models" / "ferrers.py"
    spec = importlib.util.spec_from_file_location("baseline_ferrers", path)
    module = importlib.util.module_from_spec(spec)
    # Registered: numba's cache of its kernels names their module, and
    # imports it when it loads them.
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    params = inspect.signature(module.inside_table).parameters
    inside = module.inside_table(axes2, gm) if len(params) == 2 else module.inside_table(axes2)
    return _kick_loop(module), inside


def measure(quick, repeats, baseline=None, clock=time.perf_counter):
    """Rows of ns per evaluation, per position set and contender
    (``baseline``: a code directory whose ``ferrers_kick`` is timed too;
    ``clock``: wall time or the process's CPU time)."""
    model = RotatingBar()
    axes2, gm = model._axes2, SPA02["bar_mass"]
    old = _baseline_kick(baseline, axes2, gm)
    # The model's own table: its layout differs between codes measured.
    inside = model._inside
    par = np.empty(0)
    model_loop = _model_loop(model.grad_hess_v)
    extra_loop = _extra_loop(model.extra_force)
    kick_loop = _kick_loop()
    peers = _agama()
    rows = []
    for name, Q in positions(quick).items():
        _ferrers_loop(Q, axes2, gm, inside)
        model_loop(Q, par)
        extra_loop(Q)
        tasks = {"varint ferrers_grad_hess": lambda Q=Q: _ferrers_loop(Q, axes2, gm, inside),
                 "varint model grad_hess_v": lambda Q=Q: model_loop(Q, par),
                 "varint model extra_force": lambda Q=Q: extra_loop(Q)}
        if kick_loop is not None:
            kick_loop(Q, axes2, gm, inside)
            tasks["varint ferrers_kick"] = lambda Q=Q: kick_loop(Q, axes2, gm, inside)
        if old is not None:
            old_loop, old_inside = old
            old_loop(Q, axes2, gm, old_inside)
            tasks["baseline ferrers_kick"] = (
                lambda Q=Q, f=old_loop, t=old_inside: f(Q, axes2, gm, t))
        if peers is not None:
            bar, whole = peers
            tasks["AGAMA Ferrers eval acc+der (array)"] = (
                lambda Q=Q, bar=bar: bar.eval(Q, acc=True, der=True))
            tasks["AGAMA model eval acc+der (array)"] = (
                lambda Q=Q, whole=whole: whole.eval(Q, acc=True, der=True))
            tasks["AGAMA Ferrers eval acc+der (one point a call)"] = (
                lambda few=Q[:50], bar=bar: [bar.eval(q, acc=True, der=True) for q in few])
        best, _ = interleaved(tasks, repeats, clock=clock)
        for label, seconds in best.items():
            count = 50 if "one point" in label else len(Q)
            rows.append({"points": name, "contender": label, "count": count,
                         "ns_per_eval": 1e9 * seconds / count})
        print("; ".join(f"{r['contender']}: {r['ns_per_eval']:.0f} ns" for r in rows
                        if r["points"] == name), f"({name})", flush=True)
    return rows


def defaults(repeats):
    """Per named orbit: the default step's pilots against the run
    (module docstring)."""
    w0 = np.full((6, 1), 1 / np.sqrt(6))
    out = {}
    for name in BAR_ORBITS:
        model, x0 = bar_orbit(name)
        timing: dict = {}
        for _ in range(repeats + 1):
            prov = varint.lyapunov_spectrum(model, x0, 100.0, deviations=w0,
                                            t_out=[100.0]).provenance
            for key in ("pilot", "run"):
                timing[key] = min(timing.get(key, np.inf), prov.timing[key])
        choice = prov.tau_choice
        out[name] = {"seconds": timing, "pilot_over_run": timing["pilot"] / timing["run"],
                     "tau": choice["tau"], "tried": choice["tried"],
                     "pilot_steps": choice["counts"]["steps"], "run_steps": prov.counts["steps"]}
        print(f"defaults {name}: τ = {choice['tau']:.4g}, pilots {timing['pilot'] * 1e3:.3g} ms "
              f"({choice['counts']['steps']} steps, {len(choice['tried'])} rungs) vs run "
              f"{timing['run'] * 1e3:.3g} ms ({prov.counts['steps']} steps)", flush=True)
    return out


def main(argv=None):
    def extra(parser):
        parser.add_argument("--label", default="after", help="names the code measured")
        parser.add_argument("--repeats", type=int, default=7)
        parser.add_argument("--baseline", type=Path, default=None,
                            help="a code directory whose ferrers_kick is timed beside this one")
        parser.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                            help="wall time, or the process's CPU time (every contender runs "
                                 "one thread: on a loaded machine)")

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    if args.out in (RESULTS, RESULTS / "quick"):
        args.out = args.out / "bar20"
        args.out.mkdir(parents=True, exist_ok=True)
    start = os.getloadavg()
    repeats = 1 if args.quick else args.repeats
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    rows = measure(args.quick, repeats, args.baseline, clock)
    name = f"bar_force_cost_{args.label}"
    save_csv(args.out, name, rows, COLUMNS)
    save_json(args.out, name, {"rows": rows, "defaults": defaults(repeats), "load": start,
                               "load_end": os.getloadavg(), "label": args.label,
                               "clock": args.clock})
    print(f"load {start[0]:.2f} → {os.getloadavg()[0]:.2f}")
    return rows


if __name__ == "__main__":
    main()
