"""The Kepler drift and the interaction kick of n planets over SIMD lanes:
many grid points (orbits) stepped together, the orbit index innermost.

A block of L orbits is held as a structure of arrays — the states ``X``
(6n, L) and the deviation vectors ``V`` (k, 6n, L) — and each flow is one
loop over the lanes whose body is branch-free, the layout in which LLVM
vectorises a loop (as it does the TM steppers' lanes for orbits,
:mod:`varint.codegen.interval`). Measured (studies/planetary_lanes.py,
numba 0.68): the loops of the f and g update and of the tangent map
vectorise, those of the Kepler solve and of the kick do not yet (no vector
body in their IR), and a block of 64 grid points takes as long as the
one-orbit part stepper (0.98×); these kernels are not yet what
``chaos_map`` runs.

* the drift solves every lane's Kepler equations by the common path of
  :func:`varint.kernels.kepler.solve_fast` — the series guess, one
  third-order correction, the Stiefel functions moved by their Taylor
  series — with its branches turned into selects: both the 7- and the
  12-term Stumpff series are computed and one is kept, the corrected and
  the uncorrected solution likewise. A lane that path does not settle
  (|βX²| > 4, where the closed forms with cos/sin take over; a guess or
  a correction out of range; a residual above round-off; a degenerate
  state or r ≤ 0) is marked, left untouched, and then stepped alone by the
  one-orbit flow (the model's ``apply``), which iterates as long as it
  needs: the Kepler solve's iteration count varies per point, the lanes'
  does not.
* the kick is the generated straight-line kick of
  :mod:`varint.kernels.nbody_unrolled`, its vector loop unrolled for a
  fixed k and the close-encounter test written as a select, inside one
  loop over the lanes.

Every arithmetic operation, and its order, is the one-orbit flow's, so a
lane ends bit for bit where the one-orbit path ends (the tests hold them
to it); a failure marks the lane's first coordinate as the one-orbit flow
does (NaN for a Kepler drift that cannot be solved, +inf after a close
encounter).
"""

from __future__ import annotations

import math
import re
from functools import cache

import numba
import numpy as np
from numba import njit

from . import kepler as kep
from .kepler import RESIDUAL
from .nbody import ENCOUNTER, INTERACTION, KEPLER
from .nbody_unrolled import _source

__all__ = ["drift_lanes", "kick_lanes", "lane_steps"]

# The constants of varint.kernels.kepler.stumpff (its series branch).
_SHORT, _SERIES = 0.25, 4.0
# Scratch rows per planet of the drift: the prepared state and the solution.
_RX, _RY, _RZ, _VX, _VY, _VZ, _R0, _BETA, _ETA, _ZETA, _X, _G0 = range(12)
_FIELDS = 17


@njit(inline="always")
def _solve_lane(r0, eta0, zeta0, beta, h):
    """:func:`varint.kernels.kepler.solve_fast` with its branches as
    selects and the Stumpff functions by their series only: (settled, X,
    G₀ … G₅), bit for bit solve_fast's where settled."""
    X, s = kep._guess(r0, eta0, zeta0, beta, h)
    guessed = (X * s > 0.0) & (abs(X) < 2.0 * abs(s))
    # gauss(beta, X) through stumpff's series branch.
    X2 = X * X
    z = beta * X2
    az = abs(z)
    short = az <= _SHORT
    c4 = kep._series(z, 4, 7) if short else kep._series(z, 4, 12)
    c5 = kep._series(z, 5, 7) if short else kep._series(z, 5, 12)
    c3 = 1.0 / 6.0 - z * c5
    c2 = 0.5 - z * c4
    c1 = 1.0 - z * c3
    c0 = 1.0 - z * c2
    X3 = X2 * X
    G0, G1, G2, G3, G4, G5 = c0, c1 * X, c2 * X2, c3 * X3, c4 * X3 * X, c5 * X3 * X2
    F, scale = kep._residual(X, r0, eta0, zeta0, G2, G3, h)
    first = abs(F) <= RESIDUAL * scale
    dl = -kep._correction(F, r0, eta0, zeta0, G0, G1, G2)
    small = abs(dl) <= 1e-5 * abs(X)
    H0, H1, H2, H3, H4, H5 = kep._shifted(beta, G0, G1, G2, G3, G4, G5, dl)
    Y = X + dl
    F2, scale2 = kep._residual(Y, r0, eta0, zeta0, H2, H3, h)
    second = abs(F2) <= RESIDUAL * scale2
    settled = guessed & (az <= _SERIES) & (first | (small & second))
    if first:
        return settled, X, G0, G1, G2, G3, G4, G5
    return settled, Y, H0, H1, H2, H3, H4, H5


@njit(inline="always", error_model="numpy")
def _fg(r0, eta0, zeta0, G1, G2, G3, mu, h):
    """1/r0, 1/r and the Lagrange coefficients f − 1, g, ḟ, ġ − 1 of one
    lane's Kepler step from its solved Stumpff terms (the state's update
    and its tangent's both need them: recomputed per loop, not stored, so
    each loop stays one pass over the lanes)."""
    r = r0 + eta0 * G1 + zeta0 * G2
    inv_r0 = 1.0 / r0
    inv_r = 1.0 / r
    return (inv_r0, inv_r, -mu * G2 * inv_r0, h - mu * G3, -mu * G1 * inv_r0 * inv_r,
            -mu * G2 * inv_r)


@njit(error_model="numpy")
def _solve_planet(X, i, n, mu, inv_m, h, S, bad):
    """Kepler's equation of planet ``i`` in every lane; the prepared state
    and the solution go to ``S[i]`` (fields, L), ``bad[l]`` is set where
    the lane must be stepped alone."""
    iq, ip = 3 * i, 3 * n + 3 * i
    for lane in range(X.shape[1]):
        rx, ry, rz = X[iq, lane], X[iq + 1, lane], X[iq + 2, lane]
        vx, vy, vz = X[ip, lane] * inv_m, X[ip + 1, lane] * inv_m, X[ip + 2, lane] * inv_m
        r0 = math.sqrt(rx * rx + ry * ry + rz * rz)
        v2 = vx * vx + vy * vy + vz * vz
        ok = (r0 > 0.0) & (r0 < np.inf) & (v2 < np.inf)
        beta = (2.0 * mu) / r0 - v2
        eta0 = rx * vx + ry * vy + rz * vz
        zeta0 = mu - beta * r0
        settled, Xu, G0, G1, G2, G3, G4, G5 = _solve_lane(r0, eta0, zeta0, beta, h)
        r = r0 + eta0 * G1 + zeta0 * G2
        good = ok & settled & (r > 0.0) & (r < np.inf)
        bad[lane] = bad[lane] | (not good)
        S[i, _RX, lane], S[i, _RY, lane], S[i, _RZ, lane] = rx, ry, rz
        S[i, _VX, lane], S[i, _VY, lane], S[i, _VZ, lane] = vx, vy, vz
        S[i, _R0, lane], S[i, _BETA, lane] = r0, beta
        S[i, _ETA, lane], S[i, _ZETA, lane], S[i, _X, lane] = eta0, zeta0, Xu
        S[i, _G0, lane], S[i, _G0 + 1, lane], S[i, _G0 + 2, lane] = G0, G1, G2
        S[i, _G0 + 3, lane], S[i, _G0 + 4, lane], S[i, _G0 + 5, lane] = G3, G4, G5


@njit(error_model="numpy")
def _finish_planet(X, V, k, i, n, mu, mass, inv_m, h, S, bad):
    """:func:`varint.kernels.kepler.finish` of planet ``i`` in every lane
    not marked ``bad`` (the others keep their state): the vectors first,
    which read the momenta from before the drift, then the orbit."""
    iq, ip = 3 * i, 3 * n + 3 * i
    for c in range(k):
        for lane in range(X.shape[1]):
            keep = bad[lane]
            rx, ry, rz = S[i, _RX, lane], S[i, _RY, lane], S[i, _RZ, lane]
            vx, vy, vz = S[i, _VX, lane], S[i, _VY, lane], S[i, _VZ, lane]
            r0, beta = S[i, _R0, lane], S[i, _BETA, lane]
            eta0, zeta0, Xu = S[i, _ETA, lane], S[i, _ZETA, lane], S[i, _X, lane]
            G0, G1, G2 = S[i, _G0, lane], S[i, _G0 + 1, lane], S[i, _G0 + 2, lane]
            G3, G4, G5 = S[i, _G0 + 3, lane], S[i, _G0 + 4, lane], S[i, _G0 + 5, lane]
            inv_r0, inv_r, f, g, fd, gd = _fg(r0, eta0, zeta0, G1, G2, G3, mu, h)
            fm = fd * mass
            px, py, pz = X[ip, lane], X[ip + 1, lane], X[ip + 2, lane]
            G1b = 0.5 * (G3 - Xu * G2)
            G2b = 0.5 * (2.0 * G4 - Xu * G3)
            G3b = 0.5 * (3.0 * G5 - Xu * G4)
            tb = eta0 * G2b + zeta0 * G3b
            dx, dy, dz = V[c, iq, lane], V[c, iq + 1, lane], V[c, iq + 2, lane]
            wx, wy, wz = V[c, ip, lane], V[c, ip + 1, lane], V[c, ip + 2, lane]
            dvx, dvy, dvz = wx * inv_m, wy * inv_m, wz * inv_m
            dr0 = (dx * rx + dy * ry + dz * rz) * inv_r0
            dbeta = -2.0 * mu * dr0 * inv_r0 * inv_r0 - 2.0 * (dvx * vx + dvy * vy + dvz * vz)
            deta0 = dx * vx + dy * vy + dz * vz + rx * dvx + ry * dvy + rz * dvz
            dzeta0 = -beta * dr0 - r0 * dbeta
            dX = -(Xu * dr0 + G2 * deta0 + G3 * dzeta0 + tb * dbeta) * inv_r
            dG1 = G0 * dX + G1b * dbeta
            dG2 = G1 * dX + G2b * dbeta
            dG3 = G2 * dX + G3b * dbeta
            dr = dr0 + G1 * deta0 + G2 * dzeta0 + eta0 * dG1 + zeta0 * dG2
            df = mu * (G2 * dr0 * inv_r0 - dG2) * inv_r0
            dg = -mu * dG3
            dfd = mu * (G1 * (dr0 * inv_r0 + dr * inv_r) - dG1) * inv_r0 * inv_r
            dgd = mu * (G2 * dr * inv_r - dG2) * inv_r
            dfm = dfd * mass
            V[c, iq, lane] = dx if keep else dx + (f * dx + g * dvx + df * rx + dg * vx)
            V[c, iq + 1, lane] = dy if keep else dy + (f * dy + g * dvy + df * ry + dg * vy)
            V[c, iq + 2, lane] = dz if keep else dz + (f * dz + g * dvz + df * rz + dg * vz)
            V[c, ip, lane] = wx if keep else wx + (fm * dx + gd * wx + dfm * rx + dgd * px)
            V[c, ip + 1, lane] = wy if keep else wy + (fm * dy + gd * wy + dfm * ry + dgd * py)
            V[c, ip + 2, lane] = wz if keep else wz + (fm * dz + gd * wz + dfm * rz + dgd * pz)
    for lane in range(X.shape[1]):
        keep = bad[lane]
        rx, ry, rz = S[i, _RX, lane], S[i, _RY, lane], S[i, _RZ, lane]
        vx, vy, vz = S[i, _VX, lane], S[i, _VY, lane], S[i, _VZ, lane]
        r0, eta0, zeta0 = S[i, _R0, lane], S[i, _ETA, lane], S[i, _ZETA, lane]
        G1, G2, G3 = S[i, _G0 + 1, lane], S[i, _G0 + 2, lane], S[i, _G0 + 3, lane]
        inv_r0, inv_r, f, g, fd, gd = _fg(r0, eta0, zeta0, G1, G2, G3, mu, h)
        px, py, pz = X[ip, lane], X[ip + 1, lane], X[ip + 2, lane]
        fm = fd * mass
        X[iq, lane] = rx if keep else rx + (f * rx + g * vx)
        X[iq + 1, lane] = ry if keep else ry + (f * ry + g * vy)
        X[iq + 2, lane] = rz if keep else rz + (f * rz + g * vz)
        X[ip, lane] = px if keep else px + (fm * rx + gd * px)
        X[ip + 1, lane] = py if keep else py + (fm * ry + gd * py)
        X[ip + 2, lane] = pz if keep else pz + (fm * rz + gd * pz)


@njit(error_model="numpy")
def drift_lanes(X, V, k, h, par, S, bad):
    """The Kepler drift of every planet for time ``h`` in every lane whose
    Kepler equations the common path settles; returns how many lanes it
    left (marked in ``bad``) for the one-orbit flow. ``S`` (n, 17, L) and
    ``bad`` (L,) are scratch."""
    n = X.shape[0] // 6
    omu, okm = 5 + 2 * n, 5 + 3 * n     # par offsets of μ_i and m′_i
    bad[:] = False
    for i in range(n):
        _solve_planet(X, i, n, par[omu + i], 1.0 / par[okm + i], h, S, bad)
    for i in range(n):
        km = par[okm + i]
        _finish_planet(X, V, k, i, n, par[omu + i], km, 1.0 / km, h, S, bad)
    return int(bad.sum())


def _kick_lane_source(n, jacobi, k):
    """The generated kick of :func:`varint.kernels.nbody_unrolled.kick_kernel`
    as one loop over lanes: ``x[i]`` → ``X[i, lane]``, its vector loop
    unrolled for ``k`` vectors, its close-encounter test a select."""
    lines = _source(n, jacobi).splitlines()
    head_end = next(j for j, line in enumerate(lines) if line.startswith("    q0x = "))
    enc = next(j for j, line in enumerate(lines) if line.startswith("    f2 = "))
    vec = lines.index("    for c in range(k):")
    ret = lines.index("    return met")
    out = ["def kick(X, V, h, par, met_out):", *lines[1:head_end]]
    out.append(lines[enc])
    out.append("    for lane in range(X.shape[1]):")

    def lane(line):
        return re.sub(r"\bx\[(\d+)\]", r"X[\1, lane]", line)

    out += ["    " + lane(line) for line in lines[head_end:enc]]
    out.append("        met = 0")
    for line in lines[enc + 3:vec]:       # the pairs' tests: `if met == 0 and (d2 < …):`
        test = line.strip()
        if test.startswith("if met == 0 and "):
            cond = test[len("if met == 0 and "):-1]
            out.append(f"        met = ENCOUNTER if (f2 != 0.0) & ({cond}) else met")
    for c in range(k):
        for line in lines[vec + 1:ret]:
            out.append(re.sub(r"V\[c, (\d+)\]", rf"V[{c}, \1, lane]", line))
    out.append("        met_out[lane] = met")
    return "\n".join(out) + "\n"


@cache
def kick_lanes(n, jacobi, k):
    """The compiled kick of n planets over lanes with k vectors:
    ``kick(X, V, h, par, met)``, ``met[l]`` = ENCOUNTER after a kick that
    leaves two planets of lane l within the close-encounter distance."""
    scope = {"math": math, "ENCOUNTER": ENCOUNTER}
    exec(compile(_kick_lane_source(n, jacobi, k), f"<varint planetary kick lanes n={n} k={k}>",
                 "exec"), scope)
    return numba.njit(error_model="numpy")(scope["kick"])


@cache
def lane_steps(n, jacobi, k, apply):
    """``steps(X, V, parts, h, par, n_work, n_steps)``: ``n_steps`` steps
    of the word of flows (part index ``parts[s]``, length ``h[s]``) on
    every lane of ``X`` (6n, L) and ``V`` (k, 6n, L); a lane the drift's
    common path does not settle takes that flow through ``apply``, the
    one-orbit flow (:func:`varint.kernels.nbody_unrolled.flows`). Returns
    the number of such one-orbit drifts. Only the Kepler and interaction
    parts (Jacobi coordinates).

    Raises
    ------
    ValueError
        For democratic heliocentric coordinates (their jump flow has no
        lanes).
    """
    if not jacobi:
        raise ValueError("planetary lanes step Jacobi coordinates only (Kepler drift and "
                         "interaction kick); got democratic heliocentric ones")
    kick = kick_lanes(n, jacobi, k)

    @njit(error_model="numpy")
    def steps(X, V, parts, h, par, n_work, n_steps):
        width = X.shape[1]
        S = np.empty((n, _FIELDS, width))
        bad = np.zeros(width, dtype=np.bool_)
        met = np.zeros(width, dtype=np.int64)
        x = np.empty(X.shape[0])
        W = np.empty((k, X.shape[0]))
        work = np.empty(n_work)
        alone = 0
        for _ in range(n_steps):
            for st in range(parts.shape[0]):
                if parts[st] == KEPLER:
                    if h[st] == 0.0:
                        continue
                    if drift_lanes(X, V, k, h[st], par, S, bad) == 0:
                        continue
                    for lane in range(width):
                        if not bad[lane]:
                            continue
                        alone += 1
                        x[:] = X[:, lane]
                        W[:, :] = V[:, :, lane]
                        apply(KEPLER, h[st], x, W, k, par, work)
                        X[:, lane] = x
                        V[:, :, lane] = W
                elif parts[st] == INTERACTION:
                    kick(X, V, h[st], par, met)
                    for lane in range(width):
                        if met[lane] != 0:
                            X[0, lane] = math.inf
        return alone

    return steps
