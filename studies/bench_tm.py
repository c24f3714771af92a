"""Speed of the tangent-map stepper: nanoseconds per step for every scheme,
model and number of deviation vectors, and the paper's configuration against
a plain C loop of the same algorithm compiled in the same run.

The paper's TM configuration is Hénon–Heiles R1, SBAB2C, τ = 0.05, full
spectrum (k = 4) with QR re-orthonormalisation every step. The C loop does
exactly that (modified Gram–Schmidt, log of every R_ii every step), compiled
with ``gcc -O3 -march=native`` if gcc is available; ratios within one run are
what count (the machine is shared and noisy).

Usage: ``python studies/bench_tm.py [--quick] [--csv FILE]``
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

import varint
from varint.methods import make_propagator
from varint.schemes import registered
from varint.state import RunState

C_LOOP = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
/* Hénon–Heiles, SBAB2C with corrector (g = 1/72), TM method, 4 deviation
   vectors, modified Gram–Schmidt and log(R_ii) every step. */
static void kick(double *x, double W[4][4], double h, double hc) {
    double q0 = x[0], q1 = x[1];
    double g0 = q0 + 2*q0*q1, g1 = q1 + q0*q0 - q1*q1;
    double H00 = 1 + 2*q1, H01 = 2*q0, H11 = 1 - 2*q1;
    double K00 = h*H00, K01 = h*H01, K11 = h*H11;
    double f0 = h*g0, f1 = h*g1;
    if (hc != 0.0) {
        f0 += hc*2*q0*(1 + 2*q0*q0 + 6*q1 + 2*q1*q1);
        f1 += hc*2*(q1 - 3*q1*q1 + 2*q1*q1*q1 + 3*q0*q0 + 2*q0*q0*q1);
        K00 += hc*2*(1 + 6*q0*q0 + 2*q1*q1 + 6*q1);
        K01 += hc*2*(2*q0*(3 + 2*q1));
        K11 += hc*2*(1 + 2*q0*q0 + 6*q1*q1 - 6*q1);
    }
    x[2] -= f0; x[3] -= f1;
    for (int j = 0; j < 4; j++) {
        double d0 = W[0][j], d1 = W[1][j];
        W[2][j] -= K00*d0 + K01*d1;
        W[3][j] -= K01*d0 + K11*d1;
    }
}
static void drift(double *x, double W[4][4], double h) {
    x[0] += h*x[2]; x[1] += h*x[3];
    for (int j = 0; j < 4; j++) { W[0][j] += h*W[2][j]; W[1][j] += h*W[3][j]; }
}
int main(int argc, char **argv) {
    long n = atol(argv[1]);
    double tau = 0.05, hc = -(1.0/72)*tau*tau*tau/2;
    double x[4] = {0.0, 0.558, atof(argv[2]), 0.0};
    double W[4][4] = {{1,0,0,0},{0,1,0,0},{0,0,1,0},{0,0,0,1}};
    double S[4] = {0, 0, 0, 0};
    struct timespec a, b;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
    for (long s = 0; s < n; s++) {
        kick(x, W, tau/6, hc); drift(x, W, tau/2); kick(x, W, 2*tau/3, 0.0);
        drift(x, W, tau/2); kick(x, W, tau/6, hc);
        for (int j = 0; j < 4; j++) {
            for (int a2 = 0; a2 < j; a2++) {
                double r = 0; for (int i = 0; i < 4; i++) r += W[i][a2]*W[i][j];
                for (int i = 0; i < 4; i++) W[i][j] -= r*W[i][a2];
            }
            double r = 0; for (int i = 0; i < 4; i++) r += W[i][j]*W[i][j];
            r = sqrt(r); S[j] += log(r);
            for (int i = 0; i < 4; i++) W[i][j] /= r;
        }
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
    double sec = (b.tv_sec - a.tv_sec) + 1e-9*(b.tv_nsec - a.tv_nsec);
    printf("%.6f %.10e\n", sec, S[0]/(n*tau));
    return 0;
}
"""


@contextlib.contextmanager
def c_program(source):
    """An executable compiled from the C ``source`` with ``gcc -O3
    -march=native`` in a temporary directory (removed on exit), or None
    without gcc."""
    gcc = shutil.which("gcc")
    if gcc is None:
        yield None
        return
    with tempfile.TemporaryDirectory() as tmp:
        src, exe = os.path.join(tmp, "loop.c"), os.path.join(tmp, "loop")
        with open(src, "w") as f:
            f.write(source)
        subprocess.run([gcc, "-O3", "-march=native", src, "-o", exe, "-lm"], check=True)
        yield exe


def run_c(exe, *args):
    """One run of a compiled loop: the numbers it prints, as floats."""
    out = subprocess.run([exe, *map(str, args)], check=True, capture_output=True, text=True)
    return [float(v) for v in out.stdout.split()]


def c_loop_ns_per_step(px, n_steps, repeats):
    """Best-of-``repeats`` ns/step of the C loop, or None without gcc."""
    with c_program(C_LOOP) as exe:
        if exe is None:
            return None, None
        best, x1 = np.inf, None
        for _ in range(repeats):
            seconds, x1 = run_c(exe, n_steps, repr(float(px)))
            best = min(best, seconds)
    return best / n_steps * 1e9, x1


def tm_ns_per_step(model, x0, scheme, k, n_steps, repeats, tau=0.05, every=None):
    """Best-of-``repeats`` ns/step of the TM propagator (compiled beforehand);
    ``every``: its ``renormalize_every`` (None: the adaptive default)."""
    renorm = "qr" if k else "none"
    options = {} if every is None else {"renormalize_every": every}
    prop = make_propagator("tm", model, tau, renorm, scheme=scheme, **options)
    W0 = np.eye(model.dim)[:, :k][None]
    prop.advance(RunState.start(x0[None], W0), 10)  # compile
    best = np.inf
    for _ in range(repeats):
        state = RunState.start(x0[None], W0)
        t0 = time.perf_counter()
        prop.advance(state, n_steps)
        best = min(best, time.perf_counter() - t0)
    return best / n_steps * 1e9, state


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and cases")
    parser.add_argument("--csv", help="also write the table to this CSV file")
    args = parser.parse_args(argv)
    n_steps = 200_000 if args.quick else 2_000_000
    repeats = 3

    print("# Paper configuration: R1, SBAB2C, tau = 0.05, full spectrum, QR every step")
    model, x0 = varint.paper_orbit("R1")
    c_ns, c_x1 = c_loop_ns_per_step(x0[2], n_steps, repeats)
    tm_ns, state = tm_ns_per_step(model, x0, "SBAB2C", 4, n_steps, repeats, every=1)
    tm_x1 = float(state.log_growth()[0, 0] / (n_steps * 0.05))
    sparse_ns, _ = tm_ns_per_step(model, x0, "SBAB2C", 4, n_steps, repeats)
    print(f"varint TM       {tm_ns:8.1f} ns/step   X1(t={n_steps * 0.05:g}) = {tm_x1:.6e}")
    print(f"  (its default adaptive renormalisation: {sparse_ns:.1f} ns/step)")
    if c_ns is not None:
        print(f"C loop (gcc -O3) {c_ns:7.1f} ns/step   X1 = {c_x1:.6e}")
        print(f"ratio varint / C = {tm_ns / c_ns:.2f}   (target <= 1.5); adaptive: "
              f"{sparse_ns / c_ns:.2f}")
    else:
        print("gcc not found: no C comparison")

    cases = [("HenonHeiles R1", *varint.paper_orbit("R1")),
             ("ThreeDof R2", *varint.paper_orbit("R2")),
             ("FPU n=8 R3", *varint.paper_orbit("R3"))]
    if not args.quick:
        big = varint.models.FPUBeta(1024, 1.5)
        xb = np.concatenate([0.1 * np.sin(np.linspace(0, np.pi, 1024)), np.zeros(1024)])
        cases.append(("FPU n=1024", big, xb))
    schemes = (["SBAB2C", "SABA2", "ABA864", "SRKN14a"] if args.quick
               else [s.name for s in registered(2)])
    rows = []
    print("\n# ns per step, default (adaptive) renormalisation; k = number of deviation "
          "vectors (0: orbit only)")
    for label, model, x0 in cases:
        ks = sorted({0, 1, min(model.dim, 4), model.dim if model.dim <= 16 else 8})
        steps = n_steps // max(1, model.n_dof // 8) // 4
        print(f"\n{label} (N = {model.n_dof}), {steps} steps")
        print(f"{'scheme':10}" + "".join(f"{'k=' + str(k):>10}" for k in ks)
              + f"{'grad/step':>11}")
        for name in schemes:
            ns = [tm_ns_per_step(model, x0, name, k, steps, repeats)[0] for k in ks]
            fe = varint.get_scheme(name).force_evaluations
            print(f"{name:10}" + "".join(f"{v:10.1f}" for v in ns) + f"{fe:11d}")
            rows += [(label, name, k, v) for k, v in zip(ks, ns, strict=True)]
    if args.csv:
        with open(args.csv, "w") as f:
            f.write("model,scheme,k,ns_per_step\n")
            f.writelines(f"{a},{b},{c},{d:.2f}\n" for a, b, c, d in rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
