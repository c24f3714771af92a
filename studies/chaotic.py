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

import numpy as np

import varint

__all__ = ["SAMPLE", "RADIUS", "SEED", "nearby", "reference_sample"]

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


def reference_sample(model, X, W0, t_end, tau=0.05):
    """X1(t_end) of every orbit of ``X`` (the sample of
    :func:`nearby`), from the deviation vectors ``W0`` (2N, k), by the
    reference integrator: heyoka in double precision (module docstring)."""
    W = np.repeat(np.asarray(W0)[None], len(X), axis=0)
    r = varint.lyapunov_spectrum(model, X, t_end, tau=tau, method="taylor", deviations=W,
                                 t_out=[t_end], progress=False)
    return r.exponents[:, -1, 0]
