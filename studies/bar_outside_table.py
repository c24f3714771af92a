"""What a table would save outside the Ferrers bar (issue 29, bar25): Carlson's
R_F and the two R_D of :func:`varint.models.ferrers.carlson_rf_rd` at the
chaotic bar orbit's λ, by their duplication against a piecewise polynomial
in λ made once per bar.

Outside the bar every kick finds λ and the index symbols at λ: on the
chaotic named orbit (27 % of its positions outside) the bar's kick costs
~280 ns there against 28 inside, of which the duplications of R_F and R_D
take ~130 (``studies/bar_time_split.py``, ``results/bar25``). The three
integrals are smooth in λ (their nearest singularity at λ = −c²), so a
polynomial of degree 15 on each of 16 pieces of c² + λ in ratio √2 (λ up
to 255 c²; the bar's own (a, b, c) = (6, 1.5, 0.6)) reaches round-off.

Case and method
---------------
The λ > 0 of the chaotic orbit's positions every 0.01 up to t = 100
(ABA864, τ = 0.01). The table: Chebyshev interpolation of each integral at
16 Chebyshev points per piece, from :func:`~varint.models.ferrers.carlson_rf_rd`,
turned into powers of the piece's own variable x ∈ [−1, 1] and evaluated
by Horner's rule, the piece found by a logarithm. Kept: the largest relative
difference from the duplication at every 50th λ, and the CPU time per λ of
each in a compiled loop, minimum of ``--repeats`` interleaved turns.
A measurement of a design, not varint's code: the kernels it would go
into pass the bar's constants as literals in a generated stepper's source
(768 coefficients), whose compile cost is not measured here.

Stored as ``bar_outside_table.json`` under ``--out``
(``studies/results/bar25`` by default), with the load.

Usage: ``python studies/bar_outside_table.py [--quick] [--repeats N]``.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import varint
from studies.common import RESULTS, interleaved, parse_args, save_json
from varint.models.bar import bar_orbit
from varint.models.ferrers import carlson_rf_rd, ferrers_lambda

RATIO, DEGREE, PIECES = 2 ** 0.5, 15, 16


def table(axes2):
    """(coefficients (pieces, degree + 1, 3), the pieces' edges in λ)."""
    edges = axes2[2] * RATIO ** np.arange(PIECES + 1) - axes2[2]
    nodes = np.cos(np.pi * (np.arange(DEGREE + 1) + 0.5) / (DEGREE + 1))
    coefficients = np.zeros((PIECES, DEGREE + 1, 3))
    for k in range(PIECES):
        lam = edges[k] + (nodes + 1.0) * (edges[k + 1] - edges[k]) / 2
        values = np.array([carlson_rf_rd(*(axes2 + v)) for v in lam])
        for j in range(3):
            chebyshev = np.polynomial.chebyshev.chebfit(nodes, values[:, j], DEGREE)
            coefficients[k, :, j] = np.polynomial.chebyshev.cheb2poly(chebyshev)
    return coefficients, edges


@njit(error_model="numpy")
def _from_table(lam, coefficients, edges, c2, per_log):
    k = int(np.log((c2 + lam) / c2) * per_log)
    lo, hi = edges[k], edges[k + 1]
    x = (2.0 * lam - lo - hi) / (hi - lo)
    n = coefficients.shape[1] - 1
    r0, r1, r2 = coefficients[k, n, 0], coefficients[k, n, 1], coefficients[k, n, 2]
    for d in range(n - 1, -1, -1):
        r0 = r0 * x + coefficients[k, d, 0]
        r1 = r1 * x + coefficients[k, d, 1]
        r2 = r2 * x + coefficients[k, d, 2]
    return r0, r1, r2


@njit(error_model="numpy")
def _table_loop(L, coefficients, edges, c2, per_log):
    s = 0.0
    for m in range(L.shape[0]):
        a, b, c = _from_table(L[m], coefficients, edges, c2, per_log)
        s += a + b + c
    return s


@njit(error_model="numpy")
def _duplication_loop(L, axes2):
    s = 0.0
    for m in range(L.shape[0]):
        a, b, c = carlson_rf_rd(axes2[0] + L[m], axes2[1] + L[m], axes2[2] + L[m])
        s += a + b + c
    return s


def measure(quick, repeats):
    model, x0 = bar_orbit("chaotic")
    axes2 = model._axes2
    t_end = 20.0 if quick else 100.0
    run = varint.integrate(model, x0, t_end, tau=0.01, scheme="ABA864",
                           t_out=np.arange(1, int(round(t_end / 0.01)) + 1) * 0.01)
    lam = np.array([ferrers_lambda(q * q, axes2) for q in np.asarray(run.states)[:, :3]])
    L = np.ascontiguousarray(lam[lam > 0])
    coefficients, edges = table(axes2)
    per_log = 1.0 / np.log(RATIO)
    worst = 0.0
    for v in L[::50]:
        exact = carlson_rf_rd(*(axes2 + v))
        got = _from_table(v, coefficients, edges, axes2[2], per_log)
        worst = max(worst, max(abs(g - e) / abs(e) for g, e in zip(got, exact, strict=True)))
    tasks = {"table": lambda: _table_loop(L, coefficients, edges, axes2[2], per_log),
             "duplication": lambda: _duplication_loop(L, axes2)}
    for task in tasks.values():
        task()
    best, _ = interleaved(tasks, repeats, clock=time.process_time)
    ns = {k: 1e9 * v / len(L) for k, v in best.items()}
    print(f"{len(L)} λ in ({L.min():.2e}, {L.max():.3g}); largest relative difference "
          f"{worst:.1e}; ns per λ: " + ", ".join(f"{k} {v:.1f}" for k, v in ns.items()),
          flush=True)
    return {"count": len(L), "lambda_range": [float(L.min()), float(L.max())],
            "largest_relative_difference": worst, "ns_per_lambda": ns,
            "pieces": PIECES, "degree": DEGREE, "ratio": RATIO}


def main(argv=None):
    def extra(parser):
        parser.add_argument("--repeats", type=int, default=9)

    args = parse_args(__doc__.splitlines()[0], argv, extra)
    if args.out in (RESULTS, RESULTS / "quick"):
        args.out = args.out / "bar25"
        args.out.mkdir(parents=True, exist_ok=True)
    start = os.getloadavg()
    result = measure(args.quick, 1 if args.quick else args.repeats)
    save_json(args.out, "bar_outside_table", {**result, "load": start,
                                              "load_end": os.getloadavg()})
    return result


if __name__ == "__main__":
    main()
