"""Where the time of varint's FPU-β step goes, against the plain numba loop
of studies/bench_peers.py (issue 28: n = 64 / 4096, one vector, ABA864).

One process, interleaved, minimum of repeats (CPU time), for each n:

* the whole run per step, varint (``lyapunov_spectrum``, one output, as the
  race) and the plain loop (:func:`bench_peers.fpu_tangent`);
* one kick and one drift, each fused with the vector's tangent map: varint's
  part flows (the FPUT stencil's ``apply``, one vector as a constant, as the
  part stepper compiles it) and the plain loop's, alone in a compiled loop;
* what is left of varint's step: step − (kicks × kick + drifts × drift),
  the skeleton's end of step (status check, renormalisation, accumulator);
* its parts, each alone in a compiled loop: the orbit's status check as
  the part stepper runs it (``orbit_status_wide``) and chained
  (``orbit_status``, as before), and the renormalisation of the vector
  (``renormalize`` on the stepper's (2N, 1) view of its row: one chain of
  2N additions, whose order the bits depend on) against the plain loop's
  (N additions of δq_i² + δp_i²).

Stored as ``fpu_gap.csv``.

Usage: ``python studies/fpu_gap.py [--quick] [--out DIR]``
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
from studies.bench_peers import fpu_state, fpu_tangent, seeded_vectors, stage_tables  # noqa: E402
from studies.common import interleaved, parse_args, save_csv  # noqa: E402
from varint.kernels.checks import orbit_status, orbit_status_wide, renormalize  # noqa: E402
from varint.models import fput  # noqa: E402
from varint.protocol import Renorm  # noqa: E402

TAU, SCHEME, BETA = 0.05, "ABA864", 1.5


@njit(error_model="numpy")
def plain_flows(q, p, dq, dp, a, beta, kick, reps):
    """The plain loop's kick (``kick``) or drift, ``reps`` times (the same
    lines as :func:`bench_peers.fpu_tangent`)."""
    n = q.shape[0]
    for _ in range(reps):
        if not kick:
            for i in range(n):
                q[i] += a * p[i]
                dq[i] += a * dp[i]
            continue
        r = q[0]
        fl = a * (r + beta * r * r * r)
        gl = a * (1.0 + 3.0 * beta * r * r) * dq[0]
        for i in range(n - 1):
            r = q[i + 1] - q[i]
            fr = a * (r + beta * r * r * r)
            gr = a * (1.0 + 3.0 * beta * r * r) * (dq[i + 1] - dq[i])
            p[i] += fr - fl
            dp[i] += gr - gl
            fl, gl = fr, gr
        r = -q[n - 1]
        p[n - 1] += a * (r + beta * r * r * r) - fl
        dp[n - 1] += a * (1.0 + 3.0 * beta * r * r) * (-dq[n - 1]) - gl


@njit(error_model="numpy")
def varint_flows(x, V, h, par, part, reps):
    """varint's fused flow of ``part`` (0 drift, 1 kick), one vector."""
    for _ in range(reps):
        fput._apply(part, h, x, V, 1, par, par)


@njit(error_model="numpy")
def varint_end(x, V, n, chained, reps):
    """The part stepper's end of step, ``reps`` times: the orbit's check
    (``chained``: the check before, one chain of additions) or the
    renormalisation of the vector rows ``V`` through their (2N, k) view."""
    acc_m, acc_e, r = np.ones(V.shape[0]), np.zeros(V.shape[0], dtype=np.int64), np.empty(0)
    s = 0
    for _ in range(reps):
        if chained < 0:
            s += renormalize(V.T, _QR, acc_m, acc_e, r, 2 * n, V.shape[0])
        elif chained:
            s += orbit_status(x, n, np.inf)
        else:
            s += orbit_status_wide(x, n, np.inf)
    return s


@njit(error_model="numpy")
def plain_end(dq, dp, reps):
    """The plain loop's end of step (:func:`bench_peers.fpu_tangent`)."""
    n = dq.shape[0]
    total = 0.0
    for _ in range(reps):
        norm = 0.0
        for i in range(n):
            norm += dq[i] * dq[i] + dp[i] * dp[i]
        norm = math.sqrt(norm)
        total += math.log(norm)
        for i in range(n):
            dq[i] /= norm
            dp[i] /= norm
    return total


_QR = int(Renorm.QR)


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    sizes = (64,) if args.quick else (64, 4096)
    repeats = 3 if args.quick else 7
    kinds, h, _ = stage_tables(varint.get_scheme(SCHEME), TAU)
    n_kick, n_drift = int(np.sum(kinds == 1)), int(np.sum(kinds == 0))
    rows = []
    for n in sizes:
        model, x0 = varint.models.FPUBeta(n, BETA), fpu_state(n)
        w0 = seeded_vectors(2 * n, 1, 1, seed=0)[0]
        # The race's particle-steps per run (bench_peers.fpu_case): the
        # call's fixed cost is then a small part of a step.
        steps = max(500, int((1e6 if args.quick else 4e6) / n))
        reps = max(200, steps // 10)
        t_end = steps * TAU
        x, V = x0.copy(), np.ascontiguousarray(w0.T).copy()   # not a view of w0
        q, p, dq, dp = x0[:n].copy(), x0[n:].copy(), w0[:n, 0].copy(), w0[n:, 0].copy()
        tasks = {
            "varint step": lambda m=model, x0=x0, w0=w0, t=t_end: varint.lyapunov_spectrum(
                m, x0, t, tau=TAU, n_exponents=1, scheme=SCHEME, deviations=w0, t_out=1,
                progress=False),
            "plain step": lambda x0=x0, w0=w0, s=steps: fpu_tangent(
                x0.copy(), w0[:, 0].copy(), BETA, kinds, h, s),
            "varint kick": lambda x=x, V=V, par=model.params, r=reps: varint_flows(
                x, V, 1e-12, par, 1, r),
            "plain kick": lambda q=q, p=p, dq=dq, dp=dp, r=reps: plain_flows(
                q, p, dq, dp, 1e-12, BETA, True, r),
            "varint drift": lambda x=x, V=V, par=model.params, r=reps: varint_flows(
                x, V, 1e-12, par, 0, r),
            "plain drift": lambda q=q, p=p, dq=dq, dp=dp, r=reps: plain_flows(
                q, p, dq, dp, 1e-12, BETA, False, r),
            "varint check": lambda x=x, V=V, n=n, r=reps: varint_end(x, V, n, 0, r),
            "chained check": lambda x=x, V=V, n=n, r=reps: varint_end(x, V, n, 1, r),
            "varint renorm": lambda x=x, V=V, n=n, r=reps: varint_end(x, V, n, -1, r),
            "plain renorm": lambda dq=dq, dp=dp, r=reps: plain_end(dq, dp, r),
        }
        for task in tasks.values():
            task()   # compile
        best, _ = interleaved(tasks, repeats, clock=time.process_time)
        ns = {k: v / (steps if k.endswith("step") else reps) * 1e9 for k, v in best.items()}
        row = {"n": n, "kicks_per_step": n_kick, "drifts_per_step": n_drift}
        for who in ("varint", "plain"):
            flows = n_kick * ns[f"{who} kick"] + n_drift * ns[f"{who} drift"]
            row.update({f"{who}_step_ns": ns[f"{who} step"], f"{who}_kick_ns": ns[f"{who} kick"],
                        f"{who}_drift_ns": ns[f"{who} drift"],
                        f"{who}_rest_ns": ns[f"{who} step"] - flows})
        row["step_ratio"] = ns["varint step"] / ns["plain step"]
        row["kick_ratio"] = ns["varint kick"] / ns["plain kick"]
        row["drift_ratio"] = ns["varint drift"] / ns["plain drift"]
        row.update({"varint_check_ns": ns["varint check"], "chained_check_ns": ns["chained check"],
                    "varint_renorm_ns": ns["varint renorm"],
                    "plain_renorm_ns": ns["plain renorm"]})
        rows.append(row)
        print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                        for k, v in row.items()), flush=True)
    print(f"stored {save_csv(args.out, 'fpu_gap', rows, list(rows[0]))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
