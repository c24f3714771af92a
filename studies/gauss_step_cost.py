"""Cost of varint's Gauss–Legendre path on the held-out general H
(``studies/general_h_heldout.py``): per step (the compiled flow of
:func:`varint.flows.general.general_apply` in a compiled loop, orbit and one
tangent vector), Newton/fixed-point iterations per step (the stage solve of
:func:`varint.flows.gauss.gauss_stepper`'s step, from the explicit guess as the runs
start it), and per call (``varint.lyapunov_spectrum`` over one step τ, its
fixed cost, and over t = 100, the held-out race's horizon).

Run it once on each tree to compare (the varint imported is recorded):
``PYTHONPATH=<tree> python studies/gauss_step_cost.py --label base`` then
``--label this`` from this tree. CPU time of this process (one thread),
interleaved, minimum of the repeats: on the shared machine the wall time of
an oversubscribed core counts other jobs' time. State the load (recorded).

Usage: ``python studies/gauss_step_cost.py [--quick] [--out DIR]
[--label NAME] [--repeats N]``; results in ``gauss_step_cost_<label>.json``.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from numba import njit

if __package__ in (None, ""):
    # Appended: a PYTHONPATH naming another tree's varint comes first.
    sys.path.append(str(Path(__file__).resolve().parent.parent))

import varint
from studies.common import interleaved, parse_args, save_json
from studies.general_h_heldout import build, heldout
from studies.hamiltonians import load
from varint.flows.gauss import GAUSS, gauss_stepper, gauss_work, stage_parameters
from varint.flows.general import INTEGRATORS, general_apply, general_work

#: (system, scheme, τ): the points that set the held-out ratios and the
#: longer steps of the new ladder.
CASES = (("angular coupling", "GL8", 0.2), ("angular coupling", "GL8", 0.4),
         ("angular coupling", "GL6", 0.2), ("position-dependent mass", "GL8", 0.2),
         ("position-dependent mass", "GL8", 0.4), ("three dof", "GL8", 0.2),
         ("three dof", "GL6", 0.2))
T_END = 100.0
REPEATS = 7


@njit
def _flow_loop(apply, part, n, h, x, V, par, work):
    for _ in range(n):
        apply(part, h, x, V, 1, par, work)


def _iterations(model):
    """The compiled loop counting the iterations of ``model``'s step."""
    gauss_step = gauss_stepper(model.grad_h, model.grad_hess_h)

    @njit
    def iterations(n, h, x, V, pars, A, b, c, d, E, work, prev, pt):
        total = 0
        for _ in range(n):
            prev[0] = np.nan                 # the explicit guess, as the runs start it
            _, it = gauss_step(h, x, V, 1, pars, A, b, c, d, E, work, prev, False, pt)
            total += it
        return total

    return iterations


def _start(model, x0):
    V = np.zeros((1, model.dim))
    V[0, 0] = 1.0
    return np.array(x0, dtype=float), V


def case(model, x0, scheme, tau, repeats):
    """Seconds per step and per call, and iterations per step."""
    n = int(round(T_END / tau))
    par = np.ascontiguousarray(model.parameters_at(None), dtype=np.float64)
    apply = general_apply(model.grad_h, model.grad_hess_h, model.n_dof, par.shape[0])
    work = np.empty(general_work(model.n_dof, par.shape[0]))
    part = INTEGRATORS.index(scheme)
    g = GAUSS[scheme]
    A, b, c, d, E = g.arrays
    pars = stage_parameters(par if par.shape[0] else np.zeros(1), g.stages)
    gwork = np.empty(gauss_work(model.n_dof, g.stages, 1))
    prev, pt = np.full(g.stages * model.dim, np.nan), np.zeros(1)
    w0 = np.eye(model.dim)[:, :1]

    def steps():
        x, V = _start(model, x0)
        _flow_loop(apply, part, n, tau, x, V, par, work)
        return x

    def run(t_end):
        return lambda: varint.lyapunov_spectrum(
            model, x0, t_end, tau=tau, scheme=scheme, deviations=w0, t_out=[t_end],
            energy_tol=math.inf, progress=False).state

    tasks = {"steps": steps, "call one step": run(tau), "call t=100": run(T_END)}
    for task in tasks.values():
        task()                            # compiled first
    best, _ = interleaved(tasks, repeats, clock=time.process_time)
    x, V = _start(model, x0)
    its = _iterations(model)(n, tau, x, V, pars, A, b, c, d, E, gwork, prev, pt)
    return {"system": model.name, "scheme": scheme, "tau": tau, "steps": n,
            "us_per_step": best["steps"] / n * 1e6,
            "ms_call_one_step": best["call one step"] * 1e3,
            "ms_call_t100": best["call t=100"] * 1e3, "iterations_per_step": its / n}


def main(argv=None):
    def extra(parser):
        parser.add_argument("--label", default="this")
        parser.add_argument("--repeats", type=int, default=REPEATS)

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    start = load()
    systems = heldout()
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, scheme, tau in CASES[:2] if args.quick else CASES:
            H, q, p, x0, _ = systems[name]
            model, _, _ = build(name, H, q, p)
            rows.append(case(model, np.array(x0, dtype=float), scheme, tau,
                             1 if args.quick else args.repeats))
            r = rows[-1]
            print(f"{name:<24} {scheme} τ = {tau:<4g} {r['us_per_step']:7.3f} µs/step "
                  f"{r['iterations_per_step']:6.2f} it/step  one-step call "
                  f"{r['ms_call_one_step']:6.3f} ms  t = 100 {r['ms_call_t100']:6.3f} ms",
                  flush=True)
    result = {"label": args.label, "varint": varint.__file__, "clock": "process CPU time",
              "rows": rows, "load": start, "load_end": load()}
    save_json(args.out, f"gauss_step_cost_{args.label}", result)
    print(f"load {start} → {result['load_end']}")
    return result


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
