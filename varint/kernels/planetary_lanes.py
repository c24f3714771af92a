"""The Kepler drift and the interaction kick of n planets over SIMD lanes:
many grid points (orbits) stepped together, the orbit index innermost.

A block of ``width`` orbits is held as a structure of arrays — the states
``X`` (6n, width) and the deviation vectors ``V`` (k, 6n, width) — and
each flow is one loop over the lanes whose body is branch-free, the layout
in which LLVM vectorises a loop. The kernels read the arrays flat, and the
lane count and every row's offset are compile-time constants (the kernels
are compiled per n, k and width): with a row length known only at run
time LLVM sees every row as a separate pointer and gives up ("too many
memory checks needed"), and with a planet index known only at run time it
cannot prove an index non-negative. So built, the solve, the tangent and
state updates and the kick all compile to AVX vector loops (numba's
``inspect_asm``: packed ``v…pd`` on ymm/zmm registers), measured in
studies/planetary_lanes.py.

* the drift solves every lane's Kepler equations by the common path of
  :func:`varint.kernels.kepler.solve_fast` — the series guess, one
  third-order correction, the Stiefel functions moved by their Taylor
  series — with its branches turned into selects: both the 7- and the
  12-term Stumpff series are computed and one is kept, the correction is
  always computed (zero where the guess settles). A lane that path does
  not settle (|βX²| > 4, where the closed forms with cos/sin take over; a
  guess or a correction out of range; a residual above round-off; a
  degenerate state or r ≤ 0) is marked, left untouched, and then stepped
  alone by the one-orbit flow (the model's ``apply``), which iterates as
  long as it needs: the Kepler solve's iteration count varies per point,
  the lanes' does not.
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
from .closures import cache_on_disk
from .kepler import RESIDUAL
from .nbody import ENCOUNTER, INTERACTION, KEPLER
from .nbody_unrolled import _source

__all__ = ["drift_lanes", "kick_lanes", "lane_word", "lane_steps"]

# The constants of varint.kernels.kepler.stumpff (its series branch).
_SHORT, _SERIES = 0.25, 4.0
# Scratch rows per planet of the drift (S, flat: planet, field, lane): the
# prepared state and the solution.
_RX, _RY, _RZ, _VX, _VY, _VZ, _R0, _BETA, _ETA, _ZETA, _X, _G0 = range(12)
_FIELDS = 17


@njit(inline="always")
def _solve_lane(r0, eta0, zeta0, beta, h):
    """:func:`varint.kernels.kepler.solve_fast` without branches, the
    Stumpff functions by their series only: (settled, X, G₀ … G₅), bit for
    bit solve_fast's where settled.

    Both the 7- and the 12-term series are computed and one kept (LLVM
    shares their common Horner tail). The third-order correction and the
    shifted Stiefel functions are always computed, with the residual taken
    as 0 where the guess already settles: the correction is then a signed
    zero, and adding it changes nothing — X ≠ 0 (``guessed``), and for
    |βX²| ≤ 4 G₁ … G₅ are non-zero and c₀ = 1 − z c₂ is never −0, so every
    shifted term x ± (±0) is x bit for bit. (A select of the two results
    instead lets LLVM sink the correction into a branch, and the loop then
    does not vectorise.)"""
    X, s = kep._guess(r0, eta0, zeta0, beta, h)
    guessed = (X * s > 0.0) & (abs(X) < 2.0 * abs(s))
    # gauss(beta, X) through stumpff's series branch.
    X2 = X * X
    z = beta * X2
    az = abs(z)
    short = az <= _SHORT
    c4s, c4l = kep._series(z, 4, 7), kep._series(z, 4, 12)
    c5s, c5l = kep._series(z, 5, 7), kep._series(z, 5, 12)
    c4 = c4s if short else c4l
    c5 = c5s if short else c5l
    c3 = 1.0 / 6.0 - z * c5
    c2 = 0.5 - z * c4
    c1 = 1.0 - z * c3
    c0 = 1.0 - z * c2
    X3 = X2 * X
    G0, G1, G2, G3, G4, G5 = c0, c1 * X, c2 * X2, c3 * X3, c4 * X3 * X, c5 * X3 * X2
    F, scale = kep._residual(X, r0, eta0, zeta0, G2, G3, h)
    first = abs(F) <= RESIDUAL * scale
    dl = -kep._correction(0.0 if first else F, r0, eta0, zeta0, G0, G1, G2)
    small = abs(dl) <= 1e-5 * abs(X)
    H0, H1, H2, H3, H4, H5 = kep._shifted(beta, G0, G1, G2, G3, G4, G5, dl)
    Y = X + dl
    F2, scale2 = kep._residual(Y, r0, eta0, zeta0, H2, H3, h)
    second = abs(F2) <= RESIDUAL * scale2
    settled = guessed & (az <= _SERIES) & (first | (small & second))
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


@cache
def _planet_drift(i, n, k, width):
    """The Kepler drift of planet ``i`` over ``width`` lanes: ``solve(X,
    mu, inv_m, h, S, bad)`` and ``finish(X, V, mu, mass, inv_m, h, S,
    bad)`` on the flat arrays (module docstring), every row offset and the
    lane count compile-time constants."""
    W = width
    q, p = 3 * i * W, (3 * n + 3 * i) * W          # offsets of the planet's q and p rows
    s0 = i * _FIELDS * W                           # and of its rows of S
    rows = 6 * n * W                               # one vector's length

    @njit(error_model="numpy")
    def solve(X, mu, inv_m, h, S, bad):
        """Kepler's equation of the planet in every lane; the prepared
        state and the solution go to S, ``bad[l]`` is set where lane l
        must be stepped alone."""
        for lane in range(W):
            rx, ry, rz = X[q + lane], X[q + W + lane], X[q + 2 * W + lane]
            vx = X[p + lane] * inv_m
            vy = X[p + W + lane] * inv_m
            vz = X[p + 2 * W + lane] * inv_m
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
            S[s0 + _RX * W + lane], S[s0 + _RY * W + lane], S[s0 + _RZ * W + lane] = rx, ry, rz
            S[s0 + _VX * W + lane], S[s0 + _VY * W + lane], S[s0 + _VZ * W + lane] = vx, vy, vz
            S[s0 + _R0 * W + lane], S[s0 + _BETA * W + lane] = r0, beta
            S[s0 + _ETA * W + lane], S[s0 + _ZETA * W + lane] = eta0, zeta0
            S[s0 + _X * W + lane] = Xu
            S[s0 + _G0 * W + lane], S[s0 + (_G0 + 1) * W + lane] = G0, G1
            S[s0 + (_G0 + 2) * W + lane], S[s0 + (_G0 + 3) * W + lane] = G2, G3
            S[s0 + (_G0 + 4) * W + lane], S[s0 + (_G0 + 5) * W + lane] = G4, G5

    @njit(error_model="numpy")
    def finish(X, V, mu, mass, inv_m, h, S, bad):
        """:func:`varint.kernels.kepler.finish` of the planet in every lane
        not marked ``bad`` (the others keep their state): the vectors
        first, which read the momenta from before the drift, then the
        orbit."""
        for c in range(k):
            vq, vp = c * rows + q, c * rows + p
            for lane in range(W):
                keep = bad[lane]
                rx, ry, rz = S[s0 + _RX * W + lane], S[s0 + _RY * W + lane], S[s0 + _RZ * W + lane]
                vx, vy, vz = S[s0 + _VX * W + lane], S[s0 + _VY * W + lane], S[s0 + _VZ * W + lane]
                r0, beta = S[s0 + _R0 * W + lane], S[s0 + _BETA * W + lane]
                eta0, zeta0 = S[s0 + _ETA * W + lane], S[s0 + _ZETA * W + lane]
                Xu = S[s0 + _X * W + lane]
                G0, G1 = S[s0 + _G0 * W + lane], S[s0 + (_G0 + 1) * W + lane]
                G2, G3 = S[s0 + (_G0 + 2) * W + lane], S[s0 + (_G0 + 3) * W + lane]
                G4, G5 = S[s0 + (_G0 + 4) * W + lane], S[s0 + (_G0 + 5) * W + lane]
                inv_r0, inv_r, f, g, fd, gd = _fg(r0, eta0, zeta0, G1, G2, G3, mu, h)
                fm = fd * mass
                px, py, pz = X[p + lane], X[p + W + lane], X[p + 2 * W + lane]
                G1b, G2b, G3b, tb = kep.beta_derivatives(Xu, eta0, zeta0, G2, G3, G4, G5)
                dx, dy, dz = V[vq + lane], V[vq + W + lane], V[vq + 2 * W + lane]
                wx, wy, wz = V[vp + lane], V[vp + W + lane], V[vp + 2 * W + lane]
                dvx, dvy, dvz = wx * inv_m, wy * inv_m, wz * inv_m
                df, dg, dfd, dgd = kep.fg_tangent(dx, dy, dz, dvx, dvy, dvz, rx, ry, rz, vx, vy,
                                                  vz, r0, beta, eta0, zeta0, Xu, G0, G1, G2, G3,
                                                  G1b, G2b, G3b, tb, mu, inv_r0, inv_r)
                dfm = dfd * mass
                V[vq + lane] = dx if keep else dx + (f * dx + g * dvx + df * rx + dg * vx)
                V[vq + W + lane] = dy if keep else dy + (f * dy + g * dvy + df * ry + dg * vy)
                V[vq + 2 * W + lane] = dz if keep else dz + (f * dz + g * dvz + df * rz + dg * vz)
                V[vp + lane] = wx if keep else wx + (fm * dx + gd * wx + dfm * rx + dgd * px)
                V[vp + W + lane] = wy if keep else wy + (fm * dy + gd * wy + dfm * ry + dgd * py)
                V[vp + 2 * W + lane] = wz if keep else wz + (fm * dz + gd * wz + dfm * rz
                                                               + dgd * pz)
        for lane in range(W):
            keep = bad[lane]
            rx, ry, rz = S[s0 + _RX * W + lane], S[s0 + _RY * W + lane], S[s0 + _RZ * W + lane]
            vx, vy, vz = S[s0 + _VX * W + lane], S[s0 + _VY * W + lane], S[s0 + _VZ * W + lane]
            r0, eta0 = S[s0 + _R0 * W + lane], S[s0 + _ETA * W + lane]
            zeta0 = S[s0 + _ZETA * W + lane]
            G1, G2 = S[s0 + (_G0 + 1) * W + lane], S[s0 + (_G0 + 2) * W + lane]
            G3 = S[s0 + (_G0 + 3) * W + lane]
            inv_r0, inv_r, f, g, fd, gd = _fg(r0, eta0, zeta0, G1, G2, G3, mu, h)
            px, py, pz = X[p + lane], X[p + W + lane], X[p + 2 * W + lane]
            fm = fd * mass
            X[q + lane] = rx if keep else rx + (f * rx + g * vx)
            X[q + W + lane] = ry if keep else ry + (f * ry + g * vy)
            X[q + 2 * W + lane] = rz if keep else rz + (f * rz + g * vz)
            X[p + lane] = px if keep else px + (fm * rx + gd * px)
            X[p + W + lane] = py if keep else py + (fm * ry + gd * py)
            X[p + 2 * W + lane] = pz if keep else pz + (fm * rz + gd * pz)

    return solve, finish


@cache
def drift_lanes(n, k, width):
    """The compiled Kepler drift of n planets over ``width`` lanes with k
    vectors: ``drift(X, V, h, par, S, bad)`` on the flat arrays (module
    docstring) steps every lane whose Kepler equations the common path
    settles and returns how many it left (marked in ``bad``) for the
    one-orbit flow. ``S`` (n·17·width,) and ``bad`` (width,) are
    scratch."""
    omu, okm = 5 + 2 * n, 5 + 3 * n     # par offsets of μ_i and m′_i
    drifts = [_planet_drift(i, n, k, width) for i in range(n)]

    # Written out for the planets at hand: a loop over a list of distinct
    # compiled functions is not something numba compiles.
    scope = {}
    for i, (solve, finish) in enumerate(drifts):
        scope[f"solve{i}"], scope[f"finish{i}"] = solve, finish
    body = ["def drift(X, V, h, par, S, bad):", "    bad[:] = False"]
    body += [f"    solve{i}(X, par[{omu + i}], 1.0 / par[{okm + i}], h, S, bad)" for i in range(n)]
    body += [f"    finish{i}(X, V, par[{omu + i}], par[{okm + i}], 1.0 / par[{okm + i}], h, S, bad)"
             for i in range(n)]
    body.append("    return int(bad.sum())")
    exec(compile("\n".join(body) + "\n", f"<varint planetary drift lanes n={n} k={k}>", "exec"),
         scope)
    return njit(error_model="numpy")(scope["drift"])


def _kick_lane_source(n, jacobi, k, width):
    """The generated kick of :func:`varint.kernels.nbody_unrolled.kick_kernel`
    as one loop over ``width`` lanes of the flat arrays: ``x[i]`` →
    ``X[i·width + lane]``, its vector loop unrolled for ``k`` vectors, its
    close-encounter test a select, every offset a literal."""
    lines = _source(n, jacobi).splitlines()
    head_end = next(j for j, line in enumerate(lines) if line.startswith("    q0x = "))
    enc = next(j for j, line in enumerate(lines) if line.startswith("    f2 = "))
    vec = lines.index("    for c in range(k):")
    ret = lines.index("    return met")
    rows = 6 * n
    out = ["def kick(X, V, h, par, met_out):", *lines[1:head_end]]
    out.append(lines[enc])
    tests = [line.strip()[len("if met == 0 and "):-1] for line in lines[enc + 3:vec]
             if line.strip().startswith("if met == 0 and ")]
    # The pairs' thresholds f2·par[t] are read before the loop (par is not
    # written in it, and a read of it inside would need a check that it does
    # not overlap X); (f2·par[t])·(…) is the product the one-orbit kick forms.
    scaled = sorted({int(t) for cond in tests for t in re.findall(r"f2 \* par\[(\d+)\]", cond)})
    out += [f"    f2p{t} = f2 * par[{t}]" for t in scaled]
    out.append(f"    for lane in range({width}):")

    def lane(line):
        return re.sub(r"\bx\[(\d+)\]", lambda m: f"X[{int(m[1]) * width} + lane]", line)

    out += ["    " + lane(line) for line in lines[head_end:enc]]
    out.append("        met = 0")
    for cond in tests:                    # the pairs' tests: `if met == 0 and (d2 < …):`
        cond = re.sub(r"f2 \* par\[(\d+)\]", r"f2p\1", cond)
        out.append(f"        met = ENCOUNTER if (f2 != 0.0) & ({cond}) else met")
    for c in range(k):
        for line in lines[vec + 1:ret]:
            out.append(re.sub(r"V\[c, (\d+)\]",
                              lambda m, c=c: f"V[{(c * rows + int(m[1])) * width} + lane]", line))
    out.append("        met_out[lane] = met")
    return "\n".join(out) + "\n"


@cache
def kick_lanes(n, jacobi, k, width):
    """The compiled kick of n planets over ``width`` lanes with k vectors:
    ``kick(X, V, h, par, met)`` on the flat arrays, ``met[l]`` =
    ENCOUNTER after a kick that leaves two planets of lane l within the
    close-encounter distance."""
    scope = {"math": math, "ENCOUNTER": ENCOUNTER}
    exec(compile(_kick_lane_source(n, jacobi, k, width),
                 f"<varint planetary kick lanes n={n} k={k} width={width}>", "exec"), scope)
    return numba.njit(error_model="numpy")(scope["kick"])


@cache
def lane_word(n, jacobi, k, apply, width):
    """``word(X, V, Xf, Vf, parts, h, par, S, bad, met, x, W, work)``: one
    step of the word of flows (part index ``parts[s]``, length ``h[s]``) on
    the ``width`` lanes of ``X`` (6n, width) and ``V`` (k, 6n, width), both
    C-contiguous, ``Xf`` and ``Vf`` their flat views; a lane the drift's
    common path does not settle takes that flow through ``apply``, the
    one-orbit flow (:func:`varint.kernels.nbody_unrolled.flows`). The rest
    is scratch: ``S`` (n·17·width,), ``bad`` (width,) bool, ``met``
    (width,) int, ``x`` (6n,), ``W`` (k, 6n), ``work`` (the model's
    n_work,). Returns the number of one-orbit drifts. Only the Kepler and
    interaction parts (Jacobi coordinates).

    Raises
    ------
    ValueError
        For democratic heliocentric coordinates (their jump flow has no
        lanes), or a width below 1.
    """
    if not jacobi:
        raise ValueError("planetary lanes step Jacobi coordinates only (Kepler drift and "
                         "interaction kick); got democratic heliocentric ones")
    if width < 1:
        raise ValueError(f"planetary lanes need a width of at least 1 lane; got {width}")
    kick = kick_lanes(n, jacobi, k, width)
    drift = drift_lanes(n, k, width)

    @njit(error_model="numpy")
    def word(X, V, Xf, Vf, parts, h, par, S, bad, met, x, W, work):
        alone = 0
        for st in range(parts.shape[0]):
            if parts[st] == KEPLER:
                if h[st] == 0.0:
                    continue
                if drift(Xf, Vf, h[st], par, S, bad) == 0:
                    continue
                for lane in range(width):
                    if not bad[lane]:
                        continue
                    alone += 1
                    # Element by element: no shape-error code of a slice
                    # assignment is compiled (4-7 s a process).
                    for i in range(x.shape[0]):
                        x[i] = X[i, lane]
                        for c in range(k):
                            W[c, i] = V[c, i, lane]
                    apply(KEPLER, h[st], x, W, k, par, work)
                    for i in range(x.shape[0]):
                        X[i, lane] = x[i]
                        for c in range(k):
                            V[c, i, lane] = W[c, i]
            elif parts[st] == INTERACTION:
                kick(Xf, Vf, h[st], par, met)
                for lane in range(width):
                    if met[lane] != 0:
                        X[0, lane] = math.inf
        return alone

    return word


@cache
def lane_steps(n, jacobi, k, apply, width):
    """``steps(X, V, parts, h, par, n_work, n_steps)``: ``n_steps`` steps
    of the word of flows on the ``width`` lanes of ``X`` (6n, width) and
    ``V`` (k, 6n, width), both C-contiguous (:func:`lane_word`, which
    raises for democratic coordinates); returns the number of one-orbit
    drifts."""
    word = lane_word(n, jacobi, k, apply, width)
    dim = 6 * n

    @njit(error_model="numpy")
    def steps(X, V, parts, h, par, n_work, n_steps):
        Xf = X.reshape(dim * width)
        Vf = V.reshape(k * dim * width)
        S = np.empty(n * _FIELDS * width)
        bad = np.zeros(width, dtype=np.bool_)
        met = np.zeros(width, dtype=np.int64)
        x = np.empty(dim)
        W = np.empty((k, dim))
        work = np.empty(n_work)
        alone = 0
        for _ in range(n_steps):
            alone += word(X, V, Xf, Vf, parts, h, par, S, bad, met, x, W, work)
        return alone

    return cache_on_disk(steps)
