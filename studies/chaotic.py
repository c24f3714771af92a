"""Equal accuracy on a chaotic orbit: samples of nearby orbits, not one run.

Beyond a few tens of Lyapunov times every run of a chaotic orbit — the
reference included — follows its own trajectory, and its finite-time
exponents are one draw from a distribution (C1's X1(1e4) scatters over
0.026–0.055 between equally valid runs). Whether a method is as accurate as
the reference is then a statement about distributions: the values of the
indicator over an ensemble of orbits started close to the orbit, by the
method, against the same ensemble by the reference integrator, compared by
a two-sample test (:func:`studies.claims.same_law`).

The ensemble: :data:`SAMPLE` initial conditions within :data:`RADIUS` of
the orbit's (positions displaced by seeded Gaussian steps, momenta scaled so
that the energy is the orbit's), each with the orbit's deviation vectors.
They separate from one another by e^{λt}·1e-7, so after ~16/λ (C1: t ≈ 400)
they are as different as independent trajectories of the same chaotic sea,
and the sample is that of the sea's finite-time exponents.

The reference integrates the same ensemble with heyoka's Taylor method in
double precision at its default tolerance (varint's ``method="taylor"``,
QR every τ = 0.05): its error stays at round-off, far below the 1e-7 that
separates the orbits, so it samples the true distribution; extended
precision would buy nothing after t ≈ 1e3, where any two runs have
separated anyway.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies.common import CODE, RESULTS, STARTED  # noqa: E402
from studies.paper_runs import PER_DECADE  # noqa: E402
from varint.state import initial_deviations, output_steps  # noqa: E402

__all__ = ["SAMPLE", "RADIUS", "SEED", "nearby", "reference_sample", "sample_run",
           "SAMPLE_SCHEME", "longest_sample", "sample_at"]

#: The scheme and step of :func:`sample_run`: sixth order, energy error
#: ~1e-12 on C1, an integrator other than the paper's methods it judges.
SAMPLE_SCHEME, SAMPLE_TAU = "ABA864", 0.05

#: Orbits in a sample, their distance from the orbit, and the seed of
#: their displacements.
SAMPLE = 64
RADIUS = 1e-7
SEED = 31


def nearby(model, x0, n=SAMPLE, radius=RADIUS, seed=SEED):
    """``n`` initial conditions near ``x0`` on its energy surface: the
    first is ``x0`` itself; the others have positions moved by
    ``radius``·ξ (ξ standard normal, seeded) and momenta scaled so that
    H equals H(x0) to round-off. Shape (n, 2N)."""
    x0 = np.asarray(x0, dtype=float)
    N = model.n_dof
    rng = np.random.default_rng(seed)
    X = np.repeat(x0[None], n, axis=0)
    X[1:, :N] += radius * rng.standard_normal((n - 1, N))
    e0 = float(model.energy(x0))
    for x in X[1:]:
        kinetic = e0 - float(model.potential(x[:N]))
        if not kinetic > 0:
            raise ValueError(f"no orbit of energy {e0:g} within {radius:g} of {x0.tolist()}")
        x[N:] *= np.sqrt(kinetic / float(model.kinetic(x[N:])))
    return X


def sample_run(out, orbit, t_end, fresh=False):
    """The Lyapunov spectra of the :data:`SAMPLE` orbits near the paper's
    ``orbit`` (:func:`nearby`, the vectors of seed 0 as every paper run),
    by the TM method with :data:`SAMPLE_SCHEME` at τ = 0.05 to ``t_end``,
    20 outputs per decade: stored in ``out/runs`` as a result and a JSON
    sidecar with its CPU time, resumable from a checkpoint (as
    :func:`studies.paper_runs.run`). Returns the result (exponents of shape
    (SAMPLE, n_out, 2N))."""
    model, x0 = varint.paper_orbit(orbit)
    key = (f"sample-{orbit}-tm-{SAMPLE_SCHEME}-tau{SAMPLE_TAU:g}-n{SAMPLE}-r{RADIUS:g}-"
           f"s{SEED}-t{t_end:g}")
    store = Path(out) / "runs"
    path, meta_path = store / f"{key}.npz", store / f"{key}.json"
    if not fresh and path.exists() and meta_path.exists():
        return varint.load_result(path)
    (store / "checkpoints").mkdir(parents=True, exist_ok=True)
    checkpoint = store / "checkpoints" / f"{key}.ckpt"
    if fresh:
        checkpoint.unlink(missing_ok=True)
    X = nearby(model, x0)
    W = np.repeat(initial_deviations(model.dim, model.dim, 1, seed=0), len(X), axis=0)
    t_out = output_steps(t_end, SAMPLE_TAU, per_decade=PER_DECADE) * SAMPLE_TAU
    r = varint.lyapunov_spectrum(model, X, t_end, tau=SAMPLE_TAU, scheme=SAMPLE_SCHEME,
                                 deviations=W, t_out=t_out, checkpoint=checkpoint,
                                 progress=False)
    if r.interrupted:
        raise KeyboardInterrupt(f"sample {key} interrupted; {checkpoint} resumes it")
    # Measured by varint over every session (summed in the checkpoint);
    # None only after a checkpoint whose earlier sessions were not timed.
    cpu = r.provenance.cpu_time
    r.save(path)
    meta_path.write_text(json.dumps({
        "orbit": orbit, "n": len(X), "radius": RADIUS, "seed": SEED, "scheme": SAMPLE_SCHEME,
        "tau": SAMPLE_TAU, "t_end": t_end, "cpu": cpu,
        "cpu_basis": "measured" if cpu is not None else "not measured",
        "wall": r.provenance.wall_time, "code": CODE,
        "machine": STARTED}, indent=1))
    checkpoint.unlink(missing_ok=True)
    return r


def longest_sample(out, orbit):
    """The stored :func:`sample_run` of ``orbit`` with the longest horizon
    (loaded), or None."""
    found = sorted(((float(p.stem.rsplit("-t", 1)[1]), p) for p in
                    (Path(out) / "runs").glob(f"sample-{orbit}-*.npz")
                    if p.with_suffix(".json").exists()), key=lambda tp: tp[0])
    return varint.load_result(found[-1][1]) if found else None


def sample_at(result, t):
    """X1 of every orbit of a stored sample (:func:`sample_run`) at its
    output nearest ``t`` (within a factor 1.1), or None when ``t`` is
    beyond its horizon: a chaotic sea's sticky episodes last up to ~1e7
    here (C1's TM run: X1 from 0.045 at 1e7 to 0.033 at 3e7 and back), so
    a sample's spread cannot be carried past the times it covers."""
    j = int(np.argmin(np.abs(np.log(result.t / t))))
    if abs(np.log(result.t[j] / t)) > np.log(1.1):
        return None
    return result.exponents[:, j, 0]


def reference_sample(model, X, W0, t_end, tau=0.05):
    """X1(t_end) of every orbit of ``X`` (the sample of
    :func:`nearby`), from the deviation vectors ``W0`` (2N, k), by the
    reference integrator: heyoka in double precision (module docstring)."""
    W = np.repeat(np.asarray(W0)[None], len(X), axis=0)
    r = varint.lyapunov_spectrum(model, X, t_end, tau=tau, method="taylor", deviations=W,
                                 t_out=[t_end], progress=False)
    return r.exponents[:, -1, 0]


def main(argv=None):
    """Compute (or resume, or load) the stored sample of a paper orbit."""
    parser = argparse.ArgumentParser(description="64 orbits near a paper orbit, stored.")
    parser.add_argument("orbit", choices=("R1", "C1", "C2", "R2", "R3"))
    parser.add_argument("--t-end", type=float, required=True)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    r = sample_run(args.out, args.orbit, args.t_end)
    x1 = r.exponents[:, -1, 0]
    print(f"{args.orbit}: X1(t = {r.t[-1]:g}) of {len(x1)} orbits: median {np.median(x1):.4g}, "
          f"{x1.min():.4g}–{x1.max():.4g}")
    return r


if __name__ == "__main__":
    main()
