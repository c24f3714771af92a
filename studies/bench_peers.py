"""varint against its peers as their experts drive them, at equal accuracy,
in one run: chaos maps, Lyapunov spectra, the bare orbit and FPU lattices.

Every figure is wall time on one thread (``numba.set_num_threads(1)``,
``heyoka.set_nthreads(1)``, one worker), the minimum of three repeats taken
in turn (a, b, c, a, b, c, …) so that the load of the shared machine falls
on every contender alike; a second column gives two threads. A contender
whose call takes under ``SHORT`` = 20 ms is called again within its turn
until 20 ms have passed and timed per call, as ``timeit`` does: one call
of a millisecond, made right after another contender's, runs mostly on the
caches that one left (varint's C1 run took about 1.5 times as long so). Compilation is
done and timed before the repeats and reported apart. varint is measured
through its public API with whatever it does when the script is run (its
defaults are rows of their own), so the tables can be re-made as it changes.

Maps (the headline)
-------------------
FLI, SALI and MEGNO of the orbits of the Hénon–Heiles section x = 0,
p_x ≥ 0 at H = 1/8 (the grid of :mod:`studies.bench_chaos_map`, 51 × 51:
1990 orbits), t = 1e3, orbit m starting from the seeded deviation vectors of
``varint.chaos_map`` (:func:`seeded_vectors`) in every
contender.

* varint: ``chaos_map`` with its defaults (no τ, no scheme) and with SBAB2C,
  τ = 0.05; SALI with the map's default early stopping.
* heyoka ``taylor_adaptive_batch``, batch 4 and 8 (``recommended_simd_size()``
  is 8 on AVX-512), tolerances 1e-6, 1e-9, 1e-15, on (a) the tangent system
  written by hand (orbit + δ with δ̇ = J·D²H·δ as expressions) and (b) the
  variational equations heyoka derives itself (``var_ode_sys``, k = 1, or
  2 for SALI). Non-compact mode (4 + 4k equations). All orbits in batches,
  each batch driven by ``propagate_until`` to check times every
  ``EVERY`` = 10 time units, where the deviation vectors are normalised:
  FLI = the largest accumulated ln‖w‖ at these times; SALI = the smallest
  min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖) at these times, a batch stopping once all its
  orbits are below 1e-8; MEGNO integrated as two extra ODE variables
  (Cincotta, Giordano & Simó 2003), ẏ = t·(w·ẇ)/(w·w), Ẏ = 2y/t, so
  Ȳ(t) = Y(t)/t. Why this way: heyoka controls the error of the whole state
  by its infinity norm, so a tangent vector left to grow (‖w‖ ~ e^{χt} ~
  1e30 on chaotic orbits by t = 1e3) would loosen the orbit's tolerance by
  the same factor; an expert keeps ‖w‖ = O(1). The log-norm as an ODE
  variable (L̇ = w·ẇ/w·w) does not remove that need and costs an equation,
  and one ``propagate_until``/``propagate_grid`` per batch without
  normalising is slower here (see the "driving variants" table, which
  measures these choices). MEGNO's y and Y are invariant under the
  normalisations; since 2y/t cannot be evaluated at t = 0, the clock starts
  at t = ``T_START`` = 1e-6 (a relative change of ~1e-9 in Ȳ). Two threads:
  the batches split over two workers, each with its own copy of the
  integrator — what ``ensemble_propagate_until_batch`` does, which cannot
  take the normalising loop itself; the variants table shows it on the
  one-call variant.
* pynamicalsys (if installed; ``pip install pynamicalsys``, not a varint
  dependency): its ``HamiltonianSystem("henon heiles").SALI`` per orbit (its
  own seeds), 4th-order Yoshida, τ = 0.05, stopping at 1e-8, on a sample of
  the orbits (its compilation alone takes ~30 s per process; the quick mode
  skips it unless ``--pynamicalsys``).
* The compiled limit: a plain numba loop of the SBAB2C step (τ = 0.05) with
  one tangent vector, normalised every step, the orbit index innermost
  (structure of arrays, 64 orbits at a time), FLI and MEGNO in the same run.

Classification (the same rule for every contender): the reference is
heyoka on the hand-written system, batch 8, tol 1e-15, normalising and
checking every time unit. FLI and MEGNO: chaotic when the value exceeds the
antimode of the reference's distribution of log10(value) — the minimum of
its Gaussian kernel density estimate between its two highest modes
(regular FLI ≈ ln t, chaotic ≈ χ₁t; regular Ȳ ≈ 2, chaotic ≈ χ₁t/2). SALI:
chaotic when it falls below 1e-8 at some check time. Agreement = the
fraction of orbits classified as the reference classifies them (a failed
orbit disagrees).

Spectra
-------
R1 (regular, to t = 1e5) and C1 (chaotic, to 1e4), all four exponents from
the same orthonormal initial vectors. varint ``lyapunov_spectrum`` with its
defaults, with SBAB2C at τ = 0.2 … 0.025 and with SRKN14a (order 6, the
maps' scheme) at τ = 1 … 0.25 (all with the default adaptive
renormalisation); heyoka scalar
``taylor_adaptive`` on ``var_ode_sys`` (20 equations), QR (numpy) every
1, 10 and 100 time units by a ``propagate_until`` loop, tol 1e-6 … 1e-15.
R1: the error of X1 against the extended-precision Taylor reference
(``varint.cache.reference``); the cost of each contender at the error of
varint's points is read off the other's cost–error curve (its Pareto front,
interpolated in log–log). C1 is chaotic: beyond t ~ 40/χ₁ every run,
the reference included, follows its own trajectory, so X1 differences are
statistical (:mod:`studies.chaotic`). There every contender also runs the
64 orbits started within 1e-7 of C1 on its energy surface, and "reaches
reference accuracy" when its sample of X1(t) is that of the same orbits by
the reference integrator (heyoka in double at its default tolerance, QR
every 0.05) by the two-sample Kolmogorov–Smirnov test at 1 %
(:func:`studies.claims.same_law`); the cheapest such runs are compared
(their time is that of the single run of C1 itself). The spectra are timed
in CPU time (``time.process_time``: every contender runs on one thread),
with each ratio's spread over the repeats.

Orbit only
----------
Hénon–Heiles R1, ABA864 τ = 0.05, no deviation vector: varint
``integrate`` against a plain C loop of the same 15 stages (coefficients
from ``varint.get_scheme``, ``gcc -O3 -march=native``, compiled in the run)
and heyoka (scalar, orbit only, ``propagate_grid``), ns per τ of
integration time; heyoka at varint's largest energy error is interpolated
on its tolerance curve.

FPU lattices
------------
FPU-β (β = 1.5, fixed ends, q_i = 0.5 sin(πi/(n+1)), p = 0), one deviation
vector normalised every step, ABA864 τ = 0.05, n = 8 … 4096: varint
``lyapunov_spectrum(n_exponents=1)`` (one output, at the end, as the loop;
CPU time, every contender on one thread) against a plain numba loop of the
same fused step written as an expert would (:func:`fpu_tangent`: q, p, δq,
δp in arrays of their own, one site loop per kick carrying the previous
bond's force; its X1 is printed beside varint's); at n = 256 against heyoka (``var_ode_sys``, compact mode, scalar
and batch 8, tol 1e-9 … 1e-15, normalised every 10 time units) at equal
energy error.

The disordered KG chain
-----------------------
N = 1024 (64 quick), W = 4, one deviation vector, t = 100: varint with its
defaults and with the previous default (SBAB2C on the generic stepper),
both at their pilot's step, against heyoka's Taylor method at a ladder of
tolerances, compared at equal energy error (:func:`lattice_case`).

Usage: ``python studies/bench_peers.py [--quick] [--out DIR] [--cases maps,spectra,orbit,fpu,lattice]
[--indicators fli,sali,megno] [--grid N] [--one-thread] [--spectra R1,C1] [--repeats N]
[--pynamicalsys]``. The options that cut a case down (``--indicators``,
``--grid``, ``--one-thread``, ``--spectra``) are for reduced runs on a busy
machine; the JSON records the options a run used.
"""

from __future__ import annotations

import copy
import json
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np
from numba import njit

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint
from studies.accuracy import TAU_REF
from studies.bench_chaos_map import THRESHOLD, pynamicalsys_loop, section
from studies.bench_tm import c_program, run_c
from studies.chaotic import nearby, reference_sample
from studies.claims import cost_at, pareto, same_law
from studies.common import CODE, interleaved, parse_args, save_csv, save_json
from varint.cache import reference

DRIFT, KICK = 0, 1  # the kinds of SplittingScheme.stages()
CASES = ("maps", "spectra", "orbit", "fpu", "lattice")
REPEATS = 3
#: heyoka's check and normalisation interval in the maps and the FPU case.
EVERY = 10.0
#: The reference map normalises and checks every time unit.
REF_EVERY = 1.0
REF_TOL = 1e-15
#: heyoka's MEGNO clock starts here (2y/t is 0/0 at t = 0).
T_START = 1e-6
MAP_TOLS = (1e-6, 1e-9, 1e-15)
MAP_BATCHES = (4, 8)
INDICATORS = ("fli", "sali", "megno")
#: Orbits the plain numba loop advances together (they stay in L1).
SOA_CHUNK = 64
#: Orbits pynamicalsys runs (a sample of the map; it loops in Python).
PYNAMICALSYS_SAMPLE = 100


# -- inputs, from varint's public API and documented conventions ----------------
# The compiled stepper's own tables and helpers are private and being
# replaced: the benchmark builds what it needs from the public objects.

def seeded_vectors(dim, k, n_orbits, seed=0):
    """The deviation vectors ``varint.chaos_map`` documents for orbit m of a
    map: k columns drawn from ``numpy.random.default_rng([seed, m])``,
    orthonormalised by QR with R's diagonal made positive; shape (M, dim, k)."""
    A = np.stack([np.random.default_rng([seed, m]).standard_normal((dim, k))
                  for m in range(n_orbits)])
    Q, R = np.linalg.qr(A)
    return Q * np.sign(np.diagonal(R, axis1=1, axis2=2))[:, None, :]


def stage_tables(scheme, tau):
    """A public :class:`varint.SplittingScheme` as the arrays of the plain
    loops: kinds (0 drift, 1 kick), lengths c·τ, and the corrector length
    −gτ³/2 on the first and last kick (the scheme's corrector ``e^{−gτ³/2 L_C}``; for
    a drift-first layout on zero-length kicks added at both ends)."""
    kinds = [int(kind) for kind, _ in scheme.stages()]
    h = [c * tau for _, c in scheme.stages()]
    hc = [0.0] * len(kinds)
    if scheme.corrector is not None:
        g = -scheme.corrector * tau ** 3 / 2
        if kinds[0] == DRIFT:
            kinds, h, hc = [KICK] + kinds + [KICK], [0.0] + h + [0.0], [g] + hc + [g]
        else:
            hc[0] = hc[-1] = g
    return (np.array(kinds, dtype=np.int64), np.array(h, dtype=np.float64),
            np.array(hc, dtype=np.float64))


def energy_scale(model, x):
    """|T| + |V| at ``x``: the scale of varint's relative energy errors,
    applied to the peers' errors too."""
    n = model.n_dof
    return abs(float(model.kinetic(x[n:]))) + abs(float(model.potential(x[:n])))


# -- timing --------------------------------------------------------------------

def numba_threads(n, fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` with numba on ``n`` threads (1 afterwards)."""
    numba.set_num_threads(n)
    try:
        return fn(*args, **kwargs)
    finally:
        numba.set_num_threads(1)


def timed(fn, *args, **kwargs):
    """(seconds, fn(*args, **kwargs))."""
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return time.perf_counter() - t0, out


def cold(build, *args, **kwargs):
    """(seconds, integrator): a heyoka integrator built with its in-memory
    and on-disk caches of compiled code out of the way, so the time is a
    real compilation."""
    import heyoka as hy

    state = hy.llvm_state
    enabled = state.get_diskcache_enabled()
    state.set_diskcache_enabled(False)
    state.clear_memcache()
    try:
        return timed(build, *args, **kwargs)
    finally:
        state.set_diskcache_enabled(enabled)


# -- classification ------------------------------------------------------------

def antimode(values):
    """The threshold between the two modes of log10(values): the minimum of
    the Gaussian kernel density estimate between its two highest maxima
    (Otsu's threshold of log10(values) if the estimate has one mode)."""
    from scipy.stats import gaussian_kde

    v = np.log10(values[np.isfinite(values) & (values > 0)])
    grid = np.linspace(v.min(), v.max(), 1024)
    density = gaussian_kde(v)(grid)
    peaks = np.flatnonzero((density[1:-1] > density[:-2]) & (density[1:-1] >= density[2:])) + 1
    if len(peaks) >= 2:
        a, b = sorted(peaks[np.argsort(density[peaks])[-2:]])
        return float(10 ** grid[a + np.argmin(density[a:b + 1])]), "antimode"
    s = np.sort(v)
    i = np.arange(1, len(s))
    c = np.cumsum(s)[:-1]
    w = i / len(s)
    between = w * (1 - w) * (c / i - (s.sum() - c) / (len(s) - i)) ** 2
    k = int(np.argmax(between))
    return float(10 ** (0.5 * (s[k] + s[k + 1]))), "Otsu"


def chaotic(indicator, values, threshold):
    """The classification of every orbit (NaN values: neither class)."""
    with np.errstate(invalid="ignore"):
        return values < threshold if indicator == "sali" else values > threshold


def agreement(indicator, values, ref_class, threshold):
    """Fraction of orbits classified as the reference classifies them."""
    ok = np.isfinite(values)
    return float(np.mean(ok & (chaotic(indicator, values, threshold) == ref_class)))


# -- heyoka on the Hénon–Heiles map ---------------------------------------------

def hand_system(k):
    """Hénon–Heiles and k tangent vectors written by hand: δq̇ = δp,
    δṗ = −D²V δq with D²V = [[1 + 2y, 2x], [2x, 1 − 2y]]. Returns the
    equations and each vector's rows of the state."""
    import heyoka as hy

    x, y, px, py = hy.make_vars("x", "y", "px", "py")
    eqs = [(x, px), (y, py), (px, -x - 2.0 * x * y), (py, -y - x * x + y * y)]
    for j in range(k):
        dx, dy, dpx, dpy = hy.make_vars(f"dx{j}", f"dy{j}", f"dpx{j}", f"dpy{j}")
        eqs += [(dx, dpx), (dy, dpy), (dpx, -(1.0 + 2.0 * y) * dx - 2.0 * x * dy),
                (dpy, -2.0 * x * dx - (1.0 - 2.0 * y) * dy)]
    return eqs, [slice(4 + 4 * j, 8 + 4 * j) for j in range(k)]


def derived_system(model, k):
    """The model's equations and k columns of heyoka's own variational
    equations (``var_ode_sys`` with respect to k initial conditions, whose
    columns are overwritten by the deviation vectors). Row d + i·k + j holds
    component i of vector j."""
    import heyoka as hy
    from varint.baselines.taylor import heyoka_system

    system, variables = heyoka_system(model.symbolic())
    d = len(variables)
    vsys = hy.var_ode_sys(system, variables[:k], order=1)
    return list(vsys.sys), [slice(d + j, d + d * k, k) for j in range(k)]


def megno_equations(eqs, rows):
    """MEGNO's two integrals as ODE variables (Cincotta, Giordano & Simó,
    Physica D 182, 151 (2003)): ẏ = t·(w·ẇ)/(w·w), Ẏ = 2y/t, for the vector
    in ``rows``; Ȳ(t) = Y(t)/t."""
    import heyoka as hy

    w = [eqs[i][0] for i in range(len(eqs))[rows]]
    wdot = [eqs[i][1] for i in range(len(eqs))[rows]]
    rate = hy.sum([a * b for a, b in zip(w, wdot, strict=True)]) / hy.sum([a * a for a in w])
    y, ybar = hy.make_vars("megno_y", "megno_Y")
    return [(y, hy.time * rate), (ybar, 2.0 * y / hy.time)]


class HeyokaMap:
    """One heyoka configuration of a map: the batch integrator, compiled
    once, and the expert's driver (see the module docstring).

    Parameters
    ----------
    indicator : {"fli", "sali", "megno"}
    system : {"hand", "var_ode_sys"}
    batch : int
    tol : float
    every : float
        Check and normalisation interval.
    one_call : bool
        The variant without normalising: the log-norm (FLI) or MEGNO's
        integrals as ODE variables, one ``propagate_until`` to t_end per
        batch (FLI = ln‖w(t_end)‖).
    """

    def __init__(self, model, indicator, system, batch, tol, every=EVERY, one_call=False):
        import heyoka as hy

        self.indicator, self.batch, self.every, self.one_call = indicator, batch, every, one_call
        k = 2 if indicator == "sali" else 1
        eqs, self.rows = hand_system(k) if system == "hand" else derived_system(model, k)
        self.d = model.dim
        if indicator == "megno":
            eqs += megno_equations(eqs, self.rows[0])
        elif one_call:
            w = [eqs[i][0] for i in range(len(eqs))[self.rows[0]]]
            wdot = [eqs[i][1] for i in range(len(eqs))[self.rows[0]]]
            log_norm = hy.make_vars("log_norm")
            eqs.append((log_norm, hy.sum([a * b for a, b in zip(w, wdot, strict=True)])
                        / hy.sum([a * a for a in w])))
        self.n_extra = len(eqs) - self.d * (1 + k)
        self.t_start = T_START if indicator == "megno" else 0.0
        self.compile_seconds, self.ta = cold(
            hy.taylor_adaptive_batch, eqs, np.zeros((len(eqs), batch)), tol=tol,
            compact_mode=False)

    def run(self, X, W0, t_end, threads=1):
        """The indicator of every orbit of ``X`` (M, 4) from the deviation
        vectors ``W0`` (M, 4, k)."""
        B = self.batch
        starts = list(range(0, len(X), B))
        values = np.empty(len(starts) * B)

        def work(chunk):
            ta = copy.deepcopy(self.ta) if threads > 1 else self.ta
            for b0 in chunk:
                idx = np.minimum(np.arange(b0, b0 + B), len(X) - 1)  # pad the last batch
                values[b0:b0 + B] = self._batch(ta, X[idx], W0[idx], t_end)

        if threads == 1:
            work(starts)
        else:
            with ThreadPoolExecutor(threads) as pool:
                list(pool.map(work, [starts[i::threads] for i in range(threads)]))
        return values[:len(X)]

    def _batch(self, ta, x, W, t_end):
        st = ta.state
        ta.set_time(self.t_start)
        st[:self.d] = x.T
        for j, rows in enumerate(self.rows):
            st[rows] = W[:, :, j].T
        if self.n_extra:
            st[-self.n_extra:] = 0.0
        if self.one_call:
            ta.propagate_until(t_end)
            return st[-1] if self.indicator == "fli" else st[-1] / t_end
        B = self.batch
        log_norm, fli = np.zeros(B), np.zeros(B)
        sali = np.full(B, np.inf)
        n = max(1, round(t_end / self.every))
        for j in range(1, n + 1):
            ta.propagate_until(t_end * j / n)
            norms = [np.sqrt(np.sum(st[rows] ** 2, axis=0)) for rows in self.rows]
            for rows, norm in zip(self.rows, norms, strict=True):
                st[rows] /= norm
            if self.indicator == "fli":
                log_norm += np.log(norms[0])
                np.maximum(fli, log_norm, out=fli)
            elif self.indicator == "sali":
                u, v = st[self.rows[0]], st[self.rows[1]]
                s = np.minimum(np.sqrt(np.sum((u + v) ** 2, axis=0)),
                               np.sqrt(np.sum((u - v) ** 2, axis=0)))
                np.minimum(sali, s, out=sali)
                if (sali < THRESHOLD).all():
                    break
        if self.indicator == "fli":
            return fli
        if self.indicator == "sali":
            return sali
        return st[-1] / t_end


# -- the compiled limit: a plain numba loop, orbits innermost --------------------

@njit(error_model="numpy")
def soa_fli_megno(X, W, kinds, h, hc, n_steps, tau, chunk):
    """A splitting scheme (stage tables of :func:`varint.schemes.stage_arrays`,
    corrector on kick stages) for Hénon–Heiles with one tangent vector,
    normalised every step, for the orbits in the columns of ``X`` (4, M) and
    ``W`` (4, M), ``chunk`` of them at a time, orbit index innermost.
    Returns FLI = sup ln‖w‖ and MEGNO's mean Ȳ on the step grid (the sums of
    :mod:`varint.indicators.megno`)."""
    m = X.shape[1]
    fli, log_norm = np.zeros(m), np.zeros(m)
    weighted, mean = np.zeros(m), np.zeros(m)
    for c0 in range(0, m, chunk):
        c1 = min(m, c0 + chunk)
        for s in range(n_steps):
            for st in range(kinds.shape[0]):
                a, b = h[st], hc[st]
                if kinds[st] == 0:
                    for i in range(c0, c1):
                        X[0, i] += a * X[2, i]
                        X[1, i] += a * X[3, i]
                        W[0, i] += a * W[2, i]
                        W[1, i] += a * W[3, i]
                else:
                    for i in range(c0, c1):
                        x, y = X[0, i], X[1, i]
                        gx, gy = x + 2.0 * x * y, y + x * x - y * y
                        hxx, hxy, hyy = 1.0 + 2.0 * y, 2.0 * x, 1.0 - 2.0 * y
                        fx, fy = a * gx, a * gy
                        kxx, kxy, kyy = a * hxx, a * hxy, a * hyy
                        if b != 0.0:
                            # Corrector C = ∇Vᵀ∇V: ∇C = 2 D²V ∇V,
                            # D²C = 2 (D²V D²V + D³V[∇V]), V_xxy = 2, V_yyy = −2.
                            fx += 2.0 * b * (hxx * gx + hxy * gy)
                            fy += 2.0 * b * (hxy * gx + hyy * gy)
                            kxx += 2.0 * b * (hxx * hxx + hxy * hxy + 2.0 * gy)
                            kxy += 2.0 * b * (hxx * hxy + hxy * hyy + 2.0 * gx)
                            kyy += 2.0 * b * (hxy * hxy + hyy * hyy - 2.0 * gy)
                        X[2, i] -= fx
                        X[3, i] -= fy
                        dx, dy = W[0, i], W[1, i]
                        W[2, i] -= kxx * dx + kxy * dy
                        W[3, i] -= kxy * dx + kyy * dy
            t = (s + 1) * tau
            for i in range(c0, c1):
                r = math.sqrt(W[0, i] ** 2 + W[1, i] ** 2 + W[2, i] ** 2 + W[3, i] ** 2)
                lr = math.log(r)
                log_norm[i] += lr
                fli[i] = max(fli[i], log_norm[i])
                weighted[i] += t * lr
                mean[i] += 2.0 * weighted[i] / t
                for c in range(4):
                    W[c, i] /= r
    return fli, mean / n_steps


@njit(error_model="numpy")
def fpu_tangent(x, w, beta, kinds, h, n_steps):
    """FPU-β with fixed ends and one deviation vector: the fused step of a
    splitting scheme without corrector (stage tables ``kinds``, ``h``),
    the vector normalised every step, written as an expert would: q, p, δq,
    δp in four arrays of their own (no aliasing between the loops' loads
    and stores), one site loop per kick that carries the force and the
    tangent force of the previous bond (one φ' and one φ'' per bond).
    Advances ``x`` and ``w`` in place and returns Σ ln‖w‖ (X1 = that / t)."""
    n = x.shape[0] // 2
    q, p, dq, dp = x[:n].copy(), x[n:].copy(), w[:n].copy(), w[n:].copy()
    total = 0.0
    for _ in range(n_steps):
        for st in range(kinds.shape[0]):
            a = h[st]
            if kinds[st] == 0:
                for i in range(n):
                    q[i] += a * p[i]
                    dq[i] += a * dp[i]
                continue
            # Particle i sits between bond i (left, r = q_i − q_{i−1}) and
            # bond i + 1; the walls are q_{−1} = q_n = 0.
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
        norm = 0.0
        for i in range(n):
            norm += dq[i] * dq[i] + dp[i] * dp[i]
        norm = math.sqrt(norm)
        total += math.log(norm)
        for i in range(n):
            dq[i] /= norm
            dp[i] /= norm
    x[:n], x[n:], w[:n], w[n:] = q, p, dq, dp
    return total


# -- maps -------------------------------------------------------------------------

def _config(result):
    """What varint ran: scheme and τ from the result's provenance."""
    scheme = result.provenance.method_options.get("scheme", {})
    name = scheme.get("name", "?") if isinstance(scheme, dict) else str(scheme)
    tau = result.provenance.tau
    return f"{name}, τ = {tau:g}" if isinstance(tau, (int, float)) else f"{name}, τ = {tau}"


def map_reference(model, X, W, t_end, indicators=INDICATORS):
    """The reference classification of every orbit of ``X``, for each
    indicator: heyoka on the hand-written system, batch 8, tol 1e-15,
    normalising and checking every time unit. Returns (indicator -> bool
    array "chaotic", indicator -> (threshold, rule))."""
    classes, thresholds = {}, {}
    for ind in indicators:
        hm = HeyokaMap(model, ind, "hand", 8, REF_TOL, every=REF_EVERY)
        values = hm.run(X, W[2 if ind == "sali" else 1], t_end)
        thresholds[ind] = (THRESHOLD, "fixed") if ind == "sali" else antimode(values)
        classes[ind] = chaotic(ind, values, thresholds[ind][0])
    return classes, thresholds


def maps_case(quick, repeats, with_pynamicalsys, indicators=INDICATORS, n_grid=None,
              two_threads=True):
    """The map tables (module docstring): ``indicators`` a subset of
    :data:`INDICATORS`; ``n_grid`` the grid's side (default 51, 10 in quick
    mode); ``two_threads`` False leaves out the two-thread column and times
    every contender in CPU time (``time.process_time``: all run on one
    thread then), which a loaded machine disturbs far less than wall
    time."""
    import heyoka as hy

    hy.set_nthreads(1)
    model = varint.models.HenonHeiles()
    n_grid, t_end = (n_grid or (10 if quick else 51)), (300.0 if quick else 1e3)
    grid = section(model, n_grid)
    X = grid.states
    m = len(X)
    W = {k: seeded_vectors(model.dim, k, m, seed=0) for k in (1, 2)}
    tols = (1e-6, 1e-15) if quick else MAP_TOLS
    print(f"\n# Maps: Hénon–Heiles x = 0 at H = 1/8, {n_grid}×{n_grid} grid, {m} orbits, "
          f"t = {t_end:g}; heyoka {hy.__version__}, recommended_simd_size = "
          f"{hy.recommended_simd_size()}", flush=True)

    classes, thresholds = map_reference(model, X, W, t_end, indicators)

    configs, compile_seconds = {}, {}
    for ind in indicators:
        for label, opts in (("defaults", {}), ("SBAB2C τ=0.05", {"scheme": "SBAB2C",
                                                                 "tau": 0.05})):
            key = (ind, "varint", label)
            configs[key] = opts
            compile_seconds[key], _ = timed(varint.chaos_map, model, X[:2], ind, t_end=1.0,
                                            progress=False, **opts)
            if two_threads:  # start the thread pool
                numba_threads(2, varint.chaos_map, model, X[:4], ind, t_end=1.0,
                              progress=False, **opts)
        for system in ("hand", "var_ode_sys"):
            for batch in MAP_BATCHES:
                for tol in tols:
                    hm = HeyokaMap(model, ind, system, batch, tol)
                    key = (ind, "heyoka", f"{system}, batch {batch}, tol {tol:g}")
                    configs[key], compile_seconds[key] = hm, hm.compile_seconds
    kernel_args = stage_tables(varint.get_scheme("SBAB2C"), 0.05)
    n_steps = round(t_end / 0.05)

    tasks = {}
    for key, cfg in configs.items():
        ind = key[0]
        for threads in (1, 2) if two_threads else (1,):
            if key[1] == "varint":
                tasks[key + (threads,)] = (
                    lambda cfg=cfg, ind=ind, threads=threads: numba_threads(
                        threads, varint.chaos_map, model, grid, ind, t_end=t_end,
                        progress=False, **cfg))
            else:
                tasks[key + (threads,)] = (
                    lambda cfg=cfg, ind=ind, threads=threads: cfg.run(
                        X, W[2 if ind == "sali" else 1], t_end, threads))
    if {"fli", "megno"} & set(indicators):
        compile_seconds[("soa", "numba", "")], _ = timed(
            soa_fli_megno, X[:2].T.copy(), W[1][:2, :, 0].T.copy(), *kernel_args, 2, 0.05,
            SOA_CHUNK)
        tasks[("soa", "numba", "", 1)] = lambda: soa_fli_megno(
            X.T.copy(), W[1][:, :, 0].T.copy(), *kernel_args, n_steps, 0.05, SOA_CHUNK)
    # pynamicalsys times its loop without its compilation (~30 s, first call).
    sample = np.unique(np.linspace(0, m - 1, min(m, 8 if quick else PYNAMICALSYS_SAMPLE))
                       .round().astype(int))
    py_key = ("sali", "pynamicalsys", "", 1)
    if with_pynamicalsys and "sali" in indicators:
        try:
            import pynamicalsys
        except ImportError:
            print("pynamicalsys is not installed (pip install pynamicalsys): no row for it")
        else:
            tasks[py_key] = lambda: tuple(reversed(numba_threads(1, pynamicalsys_loop,
                                                                 X[sample], t_end)))
    elif "sali" in indicators:
        print("pynamicalsys: skipped (quick mode; --pynamicalsys to run it)")
    turns = {}
    best, out = interleaved(tasks, repeats, self_timed={py_key}, turns=turns,
                            clock=time.perf_counter if two_threads else time.process_time)

    rows = []
    for (ind, peer, label, threads), seconds in best.items():
        if threads != 1 or peer in ("numba", "pynamicalsys"):
            continue
        result = out[(ind, peer, label, 1)]
        values = result.values if peer == "varint" else result
        row = {"indicator": ind, "peer": peer,
               "config": f"{label} ({_config(result)})" if peer == "varint" else label,
               "orbits": m, "orbits_per_s": m / seconds,
               "orbits_per_s_2_threads": m / best[(ind, peer, label, 2)] if two_threads
               else None,
               "agreement": agreement(ind, values, classes[ind], thresholds[ind][0]),
               "compile_s": compile_seconds[(ind, peer, label)],
               "turn_seconds": turns[(ind, peer, label, 1)]}
        rows.append(row)
    for ind, values in zip(("fli", "megno"), out.get(("soa", "numba", "", 1), ()), strict=False):
        if ind not in indicators:
            continue
        rows.append({"indicator": ind, "peer": "numba",
                     "config": "plain loop, SBAB2C τ=0.05, SoA (FLI and MEGNO in one run)",
                     "orbits": m, "orbits_per_s": m / best[("soa", "numba", "", 1)],
                     "orbits_per_s_2_threads": None,
                     "agreement": agreement(ind, values, classes[ind], thresholds[ind][0]),
                     "compile_s": compile_seconds[("soa", "numba", "")]})
    if py_key in best:
        rows.append({"indicator": "sali", "peer": "pynamicalsys",
                     "config": f"{pynamicalsys.__version__}, svy4 τ=0.05, per-orbit loop, "
                               f"{len(sample)}-orbit sample",
                     "orbits": len(sample), "orbits_per_s": len(sample) / best[py_key],
                     "orbits_per_s_2_threads": None,
                     "agreement": agreement("sali", out[py_key], classes["sali"][sample],
                                            THRESHOLD),
                     "compile_s": None})
    base = {ind: next(r["orbits_per_s"] for r in rows
                      if r["indicator"] == ind and r["peer"] == "varint")
            for ind in indicators}
    for row in rows:
        row["vs_varint_defaults"] = row["orbits_per_s"] / base[row["indicator"]]

    variants = map_variants(model, X, W, t_end, classes, thresholds, repeats, quick,
                            [i for i in ("fli", "megno") if i in indicators])
    return {"grid": n_grid, "orbits": m, "t_end": t_end, "rows": rows, "variants": variants,
            "clock": "wall" if two_threads else "cpu",
            "equal_quality": equal_quality(rows), "thresholds": {k: {"value": v[0], "rule": v[1]} for k, v in thresholds.items()},
            "chaotic_fraction": {k: float(np.mean(v)) for k, v in classes.items()},
            "heyoka": hy.__version__, "simd_size": hy.recommended_simd_size()}


def equal_quality(rows):
    """The issue's headline ratios, per indicator: varint's defaults against
    (a) heyoka hand-written, batch 8, tol 1e-6 and (b) the fastest heyoka
    configuration whose agreement with the reference is at least varint's
    (None if no configuration reaches it)."""
    out = []
    for ind in dict.fromkeys(r["indicator"] for r in rows):
        v = next(r for r in rows if r["indicator"] == ind and r["peer"] == "varint")
        heyoka = [r for r in rows if r["indicator"] == ind and r["peer"] == "heyoka"]
        fixed = next((r for r in heyoka if r["config"] == "hand, batch 8, tol 1e-06"), None)
        good = [r for r in heyoka if r["agreement"] >= v["agreement"]]
        best = max(good, key=lambda r: r["orbits_per_s"]) if good else None
        out.append({"indicator": ind, "varint": v["config"], "varint_orbits_per_s":
                    v["orbits_per_s"], "varint_agreement": v["agreement"],
                    "hy_b8_1e6_agreement": None if fixed is None else fixed["agreement"],
                    "varint_over_hy_b8_1e6": None if fixed is None
                    else v["orbits_per_s"] / fixed["orbits_per_s"],
                    "spread_hy_b8_1e6": None if fixed is None or "turn_seconds" not in v
                    else _spread(fixed, v),
                    "heyoka_equal": None if best is None else best["config"],
                    "heyoka_equal_agreement": None if best is None else best["agreement"],
                    "varint_over_heyoka_equal": None if best is None
                    else v["orbits_per_s"] / best["orbits_per_s"],
                    "spread_heyoka_equal": None if best is None or "turn_seconds" not in v
                    else _spread(best, v)})
    return out


def map_variants(model, X, W, t_end, classes, thresholds, repeats, quick, indicators):
    """How the driving choices change heyoka's FLI and MEGNO maps (batch 8,
    hand-written, tol 1e-9): the normalisation interval, and one call per
    batch without normalising — there also through
    ``ensemble_propagate_until_batch`` with one and two threads."""
    import heyoka as hy

    tol, batch = 1e-9, 8
    m = len(X)
    tasks = {}
    for ind in indicators:
        for every in (1.0, EVERY, 100.0):
            hm = HeyokaMap(model, ind, "hand", batch, tol, every=every)
            key = (ind, f"normalise every {every:g} (loop of propagate_until)", 1)
            tasks[key] = lambda hm=hm: hm.run(X, W[1], t_end)
        hm = HeyokaMap(model, ind, "hand", batch, tol, one_call=True)
        key = (ind, "no normalising, one propagate_until per batch", 1)
        tasks[key] = lambda hm=hm: hm.run(X, W[1], t_end)
        for threads in (1, 2):
            key = (ind, "no normalising, ensemble_propagate_until_batch", threads)
            tasks[key] = lambda hm=hm, threads=threads: _ensemble(hm, X, W[1], t_end, threads)
    best, out = interleaved(tasks, 1 if quick else repeats)
    rows = []
    for (ind, label, threads), seconds in best.items():
        rows.append({"indicator": ind, "driving": label, "threads": threads,
                     "orbits_per_s": m / seconds,
                     "agreement": agreement(ind, out[(ind, label, threads)], classes[ind],
                                            thresholds[ind][0])})
    print(f"(variants: heyoka hand-written, batch {batch}, tol {tol:g}, "
          f"{hy.__version__})")
    return rows


def _ensemble(hm, X, W, t_end, threads):
    """The one-call variant through ``heyoka.ensemble_propagate_until_batch``:
    iteration i integrates batch i."""
    import heyoka as hy

    B, d = hm.batch, hm.d
    starts = list(range(0, len(X), B))

    def gen(ta, i):
        idx = np.minimum(np.arange(starts[i], starts[i] + B), len(X) - 1)
        ta.set_time(hm.t_start)
        ta.state[:d] = X[idx].T
        ta.state[hm.rows[0]] = W[idx, :, 0].T
        ta.state[-hm.n_extra:] = 0.0
        return ta

    res = hy.ensemble_propagate_until_batch(hm.ta, t_end, len(starts), gen,
                                            max_workers=threads)
    last = np.concatenate([r[0].state[-1] for r in res])[:len(X)]
    return last if hm.indicator == "fli" else last / t_end


# -- spectra ------------------------------------------------------------------------

def heyoka_spectrum(model, tol):
    """A scalar heyoka integrator of the orbit and its full 2N × 2N
    variational matrix (``var_ode_sys`` with respect to every state
    variable), compiled once; returns (run, compile seconds) with
    ``run(x0, W0, t_end, every)`` -> the exponents at t_end, QR every
    ``every`` time units."""
    import heyoka as hy
    from varint.baselines.taylor import heyoka_system

    system, variables = heyoka_system(model.symbolic())
    d = len(variables)
    seconds, ta = cold(hy.taylor_adaptive, hy.var_ode_sys(system, hy.var_args.vars, order=1),
                        np.zeros(d * (1 + d)), tol=tol)

    def run(x0, W0, t_end, every):
        ta.time = 0.0
        ta.state[:d] = x0
        ta.state[d:] = W0.ravel()
        total = np.zeros(d)
        n = max(1, round(t_end / every))
        for j in range(1, n + 1):
            ta.propagate_until(t_end * j / n)
            Q, R = np.linalg.qr(ta.state[d:].reshape(d, d))
            diag = np.diagonal(R)
            total += np.log(np.abs(diag))
            ta.state[d:] = (Q * np.sign(diag)).ravel()
        return total / t_end

    return run, seconds


def _spread(slow, fast):
    """(smallest, largest) over the turns of the ratio of two rows' times."""
    ratios = [a / b for a, b in zip(slow["turn_seconds"], fast["turn_seconds"], strict=True)]
    return [min(ratios), max(ratios)]


def spectra_case(quick, repeats, names=("R1", "C1")):
    """The spectrum tables (module docstring) of the paper orbits ``names``."""
    horizons = {"R1": 1e3, "C1": 200.0} if quick else {"R1": 1e5, "C1": 1e4}
    horizons = {name: horizons[name] for name in names}
    taus = (0.1, 0.05) if quick else (0.2, 0.1, 0.05, 0.025)
    high_taus = (0.5,) if quick else (1.0, 0.5, 0.25)
    tols = (1e-6, 1e-12) if quick else (1e-6, 1e-9, 1e-12, 1e-15)
    everies = (1.0, 10.0, 100.0)
    out = {}
    for name, t_end in horizons.items():
        model, x0 = varint.paper_orbit(name)
        W0 = seeded_vectors(model.dim, model.dim, 1, seed=0)[0]
        print(f"\n# Spectra: {name} to t = {t_end:g} (extended-precision reference: cached, "
              "else computed now)", flush=True)
        ref = reference(model, x0, t_end, tau=TAU_REF, kind="lyapunov_spectrum",
                        deviations=W0, t_out=20)
        x1_ref = float(ref.exponents[-1, 0])
        late = ref.exponents[ref.t >= t_end / 2 - 1e-9, 0]
        spread = float(late.max() - late.min())

        def vt(model=model, x0=x0, t_end=t_end, W0=W0, **opts):
            return lambda: varint.lyapunov_spectrum(model, x0, t_end, deviations=W0,
                                                    t_out=[t_end], progress=False, **opts)

        configs = {("varint", "defaults", None): {}}
        for tau in taus:
            configs[("varint", "SBAB2C", tau)] = {"scheme": "SBAB2C", "tau": tau}
        # What an expert after speed would pick: a sixth-order scheme at
        # large steps (the maps' default scheme).
        for tau in high_taus:
            configs[("varint", "SRKN14a", tau)] = {"scheme": "SRKN14a", "tau": tau}
        tasks = {key: vt(**opts) for key, opts in configs.items()}
        compile_s = {}
        compile_s["varint"], _ = timed(varint.lyapunov_spectrum, model, x0, 1.0,
                                       deviations=W0, progress=False)
        runs = {}
        for tol in tols:
            run, compile_s[f"heyoka tol {tol:g}"] = heyoka_spectrum(model, tol)
            for every in everies:
                runs[("heyoka", f"QR every {every:g}", tol)] = (run, every)
                tasks[("heyoka", f"QR every {every:g}", tol)] = (
                    lambda run=run, every=every, x0=x0, W0=W0, t_end=t_end:
                    run(x0, W0, t_end, every))
        turns = {}
        best, res = interleaved(tasks, repeats, clock=time.process_time, turns=turns)
        samples = {}
        if name != "R1":
            # Chaotic: X1 of 64 nearby orbits by each contender against the
            # reference integrator's (studies.chaotic).
            X = nearby(model, x0)
            Ws = np.repeat(W0[None], len(X), axis=0)
            samples["reference"] = reference_sample(model, X, W0, t_end)
            for key in tasks:
                if key[0] == "varint":
                    samples[key] = varint.lyapunov_spectrum(
                        model, X, t_end, deviations=Ws, t_out=[t_end], progress=False,
                        **configs[key]).exponents[:, -1, 0]
                else:
                    run, every = runs[key]
                    samples[key] = np.array([run(x, W0, t_end, every)[0] for x in X])
        rows = []
        for (peer, series, param), seconds in best.items():
            X = res[(peer, series, param)]
            if peer == "varint":
                X, config = X.exponents[-1], _config(X)
            label = (f"defaults ({config})" if param is None and peer == "varint"
                     else f"{series} τ={param:g}" if peer == "varint"
                     else f"{series}, tol {param:g}")
            row = {"orbit": name, "peer": peer, "series": series, "config": label,
                   "seconds": seconds, "turn_seconds": turns[(peer, series, param)],
                   "X1": float(X[0]), "X1_error": abs(float(X[0]) - x1_ref)}
            if samples:
                law = same_law(samples[(peer, series, param)], samples["reference"])
                row.update(same_law=law.holds, same_law_p=law.value,
                           sample_median=float(np.median(samples[(peer, series, param)])))
            rows.append(row)
        fronts = {}
        for row in rows:
            fronts.setdefault((row["peer"], row["series"]), []).append(
                (row["seconds"], row["X1_error"]))
        fronts = {k: pareto(v) for k, v in fronts.items()}
        equal = []
        if name == "R1":
            for row in (r for r in rows if r["peer"] == "varint"):
                for (peer, series), front in fronts.items():
                    if peer != "heyoka":
                        continue
                    cost, how = cost_at(front, row["X1_error"])
                    equal.append({"orbit": name, "varint": row["config"],
                                  "X1_error": row["X1_error"], "varint_s": row["seconds"],
                                  "heyoka": series, "heyoka_s": cost, "how": how,
                                  "heyoka_over_varint": None if cost is None
                                  else cost / row["seconds"]})
        else:
            cheapest = {}
            for row in rows:
                key = "varint" if row["peer"] == "varint" else f"heyoka {row['series']}"
                if row["same_law"] and (key not in cheapest
                                        or row["seconds"] < cheapest[key]["seconds"]):
                    cheapest[key] = row
            v = cheapest.get("varint")
            for key, row in cheapest.items():
                if key != "varint":
                    equal.append({"orbit": name, "varint": None if v is None else v["config"],
                                  "X1_error": row["X1_error"],
                                  "varint_s": None if v is None else v["seconds"],
                                  "heyoka": row["config"], "heyoka_s": row["seconds"],
                                  "how": "cheapest with the reference's X1 distribution",
                                  "heyoka_over_varint": None if v is None
                                  else row["seconds"] / v["seconds"],
                                  "spread": None if v is None else _spread(row, v)})
        out[name] = {"t_end": t_end, "X1_ref": x1_ref, "spread": spread, "rows": rows,
                     "equal_error": equal, "compile_s": compile_s}
        if samples:
            ref_sample = samples["reference"]
            out[name]["reference_sample"] = {
                "n": len(ref_sample), "median": float(np.median(ref_sample)),
                "min": float(ref_sample.min()), "max": float(ref_sample.max())}
    return out


# -- orbit only -------------------------------------------------------------------------

def c_orbit_source(scheme, tau):
    """A plain C loop of ``scheme``'s stages for the Hénon–Heiles orbit,
    coefficients as literals; prints seconds, the largest |ΔH| at the checks
    and the final state."""
    lines = []
    for kind, c in varint.get_scheme(scheme).stages():
        h = repr(float(c * tau))
        if kind == DRIFT:
            lines.append(f"q0 += {h} * p0; q1 += {h} * p1;")
        else:
            lines.append(f"p0 -= {h} * (q0 + 2.0 * q0 * q1); "
                         f"p1 -= {h} * (q1 + q0 * q0 - q1 * q1);")
    stages = "\n            ".join(lines)
    return f"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
/* Hénon–Heiles orbit, {scheme} at tau = {tau!r}: {len(lines)} stages per step. */
static double energy(double q0, double q1, double p0, double p1) {{
    return 0.5 * (p0 * p0 + p1 * p1) + 0.5 * (q0 * q0 + q1 * q1) + q0 * q0 * q1
           - q1 * q1 * q1 / 3.0;
}}
int main(int argc, char **argv) {{
    long checks = atol(argv[1]), every = atol(argv[2]);
    double q0 = atof(argv[3]), q1 = atof(argv[4]), p0 = atof(argv[5]), p1 = atof(argv[6]);
    double e0 = energy(q0, q1, p0, p1), worst = 0.0;
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long c = 0; c < checks; c++) {{
        for (long s = 0; s < every; s++) {{
            {stages}
        }}
        double e = fabs(energy(q0, q1, p0, p1) - e0);
        if (e > worst) worst = e;
    }}
    clock_gettime(CLOCK_MONOTONIC, &b);
    double sec = (b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec);
    printf("%.9f %.17e %.17e %.17e %.17e %.17e\\n", sec, worst, q0, q1, p0, p1);
    return 0;
}}
"""


def orbit_case(quick, repeats):
    import heyoka as hy

    model, x0 = varint.paper_orbit("R1")
    tau, scheme, checks = 0.05, "ABA864", 100
    t_end = 1e3 if quick else 1e5
    n = round(t_end / tau)
    scale = float(energy_scale(model, x0))
    print(f"\n# Orbit only: Hénon–Heiles R1, {scheme} τ = {tau}, t = {t_end:g} ({n} steps)",
          flush=True)
    tasks = {("varint", f"integrate, {scheme} τ={tau:g}"): lambda: float(np.max(
        varint.integrate(model, x0, t_end, tau=tau, scheme=scheme, t_out=checks,
                         progress=False).energy_error))}
    varint.integrate(model, x0, 1.0, tau=tau, scheme=scheme, progress=False)  # compile
    tols = (1e-9, 1e-12, 1e-15) if quick else (1e-6, 1e-9, 1e-12, 1e-15)
    x, y, px, py = hy.make_vars("x", "y", "px", "py")
    eqs = [(x, px), (y, py), (px, -x - 2.0 * x * y), (py, -y - x * x + y * y)]
    grid = np.linspace(0.0, t_end, checks + 1)
    e0 = model.energy(x0)

    def heyoka_run(ta):
        ta.time = 0.0
        ta.state[:] = x0
        states = ta.propagate_grid(grid)[-1]
        return float(np.max(np.abs(model.energy(states) - e0)) / scale)

    for tol in tols:
        ta = hy.taylor_adaptive(eqs, np.zeros(4), tol=tol)
        tasks[("heyoka", f"scalar, propagate_grid, tol {tol:g}")] = lambda ta=ta: heyoka_run(ta)
    with c_program(c_orbit_source(scheme, tau)) as exe:
        if exe is not None:
            args = (checks, n // checks, *map(repr, map(float, x0)))
            c_key = ("C", f"gcc -O3 -march=native, {scheme} τ={tau:g}")

            def c_loop():
                seconds, worst = run_c(exe, *args)[:2]
                return seconds, worst / scale

            tasks[c_key] = c_loop
        else:
            c_key = None
            print("gcc not found: no C loop")
        best, res = interleaved(tasks, repeats, self_timed={c_key})
    rows = []
    for (peer, label), seconds in best.items():
        err = res[(peer, label)]
        rows.append({"peer": peer, "config": label, "ns_per_tau": seconds / n * 1e9,
                     "energy_error": err})
    front = pareto([(r["ns_per_tau"], r["energy_error"]) for r in rows if r["peer"] == "heyoka"])
    v = rows[0]
    cost, how = cost_at(front, v["energy_error"])
    c = next((r for r in rows if r["peer"] == "C"), None)
    return {"t_end": t_end, "steps": n, "rows": rows,
            "heyoka_at_varint_error": {"ns_per_tau": cost, "how": how,
                                       "heyoka_over_varint": None if cost is None
                                       else cost / v["ns_per_tau"]},
            "varint_over_C": None if c is None else v["ns_per_tau"] / c["ns_per_tau"]}


# -- FPU --------------------------------------------------------------------------------

def fpu_state(n):
    """q_i = 0.5 sin(πi/(n+1)), p = 0 (as in studies/stress.py)."""
    i = np.arange(1, n + 1)
    return np.concatenate([0.5 * np.sin(np.pi * i / (n + 1)), np.zeros(n)])


def fpu_case(quick, repeats):
    import heyoka as hy
    from varint.baselines.taylor import heyoka_system

    tau, scheme, beta = 0.05, "ABA864", 1.5
    sizes = (8, 64) if quick else (8, 64, 256, 1024, 4096)
    n_hy = 64 if quick else 256
    budget = 2e5 if quick else 4e6  # particle-steps per run
    kinds, h, _ = stage_tables(varint.get_scheme(scheme), tau)
    print(f"\n# FPU-β (β = {beta}), one deviation vector, {scheme} τ = {tau}", flush=True)
    rows, tasks, meta = [], {}, {}
    for n in sizes:
        model, x0 = varint.models.FPUBeta(n, beta), fpu_state(n)
        w0 = seeded_vectors(2 * n, 1, 1, seed=0)[0]
        steps = max(500, int(budget / n))
        t_end = steps * tau
        varint.lyapunov_spectrum(model, x0, tau, tau=tau, n_exponents=1, scheme=scheme,
                                 deviations=w0, progress=False)  # compile
        fpu_tangent(x0.copy(), w0[:, 0].copy(), beta, kinds, h, 1)

        def vrun(model=model, x0=x0, w0=w0, t_end=t_end):
            r = varint.lyapunov_spectrum(model, x0, t_end, tau=tau, n_exponents=1,
                                         scheme=scheme, deviations=w0, t_out=1,
                                         progress=False)
            return float(r.exponents[-1, 0]), float(np.max(r.energy_error))

        def nrun(x0=x0, w0=w0, steps=steps, t_end=t_end):
            return fpu_tangent(x0.copy(), w0[:, 0].copy(), beta, kinds, h, steps) / t_end

        tasks[("varint", n)], tasks[("numba", n)] = vrun, nrun
        meta[n] = (steps, t_end)
    # heyoka at one size: scalar and batch 8, normalising every EVERY.
    model, x0 = varint.models.FPUBeta(n_hy, beta), fpu_state(n_hy)
    d = 2 * n_hy
    system, variables = heyoka_system(model.symbolic())
    vsys = hy.var_ode_sys(system, variables[:1], order=1)
    t_hy = meta[n_hy][1]
    w0 = seeded_vectors(d, 1, 8, seed=0)
    scale = float(energy_scale(model, x0))
    e0 = model.energy(x0)
    compile_s = {}
    for tol in (1e-6, 1e-12) if quick else (1e-6, 1e-9, 1e-12, 1e-15):
        for batch in (1, 8):
            key = ("heyoka", f"{'scalar' if batch == 1 else 'batch 8'}, tol {tol:g}")
            if batch == 1:
                compile_s[key], ta = cold(hy.taylor_adaptive, vsys, np.zeros(2 * d),
                                           tol=tol, compact_mode=True)
            else:
                compile_s[key], ta = cold(hy.taylor_adaptive_batch, vsys,
                                           np.zeros((2 * d, batch)), tol=tol,
                                           compact_mode=True)
            tasks[key] = lambda ta=ta, batch=batch: _fpu_heyoka(ta, batch, x0, w0, t_hy, e0,
                                                                 scale, model)
    # CPU time: every contender runs on one thread, and on a loaded machine
    # the wall time of a 1 ms call is mostly the other jobs' (wall-clock
    # ratios of one build ranged 1.35–1.95 at n = 4096 under load 10).
    best, res = interleaved(tasks, repeats, clock=time.process_time)
    for n in sizes:
        steps, t_end = meta[n]
        (x1, err), x1_numba = res[("varint", n)], res[("numba", n)]
        rows.append({"n": n, "steps": steps, "varint_ns_per_step": best[("varint", n)] / steps
                     * 1e9, "numba_ns_per_step": best[("numba", n)] / steps * 1e9,
                     "varint_over_numba": best[("varint", n)] / best[("numba", n)],
                     "X1_varint": x1, "X1_numba": x1_numba, "energy_error": err})
    hy_rows = []
    for key, seconds in best.items():
        if key[0] != "heyoka":
            continue
        batch = 1 if key[1].startswith("scalar") else 8
        x1, err = res[key]
        hy_rows.append({"n": n_hy, "config": key[1], "ns_per_tau_per_orbit":
                        seconds / batch / (t_hy / tau) * 1e9, "energy_error": err,
                        "X1": x1, "compile_s": compile_s[key]})
    v = next(r for r in rows if r["n"] == n_hy)
    equal = {}
    for mode in ("scalar", "batch 8"):
        front = pareto([(r["ns_per_tau_per_orbit"], r["energy_error"]) for r in hy_rows
                        if r["config"].startswith(mode)])
        cost, how = cost_at(front, v["energy_error"])
        equal[mode] = {"ns_per_tau_per_orbit": cost, "how": how,
                       "heyoka_over_varint": None if cost is None
                       else cost / v["varint_ns_per_step"]}
    return {"rows": rows, "heyoka": hy_rows, "heyoka_n": n_hy, "heyoka_t_end": t_hy,
            "equal_energy_error": equal}


# -- the disordered KG chain with defaults --------------------------------------------------

def lattice_case(quick, repeats):
    """The disordered KG chain (W = 4, a central block of energy density
    0.1), one deviation vector, to t_end: varint with its defaults (the
    chain's own scheme on its part stepper at the pilot's step; every call
    runs its pilot) and with the previous default (SBAB2C on the generic
    stepper, also at its pilot's step), against heyoka's Taylor method on
    ``var_ode_sys`` (varint's ``taylor`` baseline, compact mode,
    renormalised every time unit) at a ladder of tolerances; heyoka's cost
    at each varint run's energy error is interpolated on its cost–error
    front. Every run stores 10 outputs."""
    n = 64 if quick else 1024
    t_end = 20.0 if quick else 100.0
    # From loose (heyoka's error reaches varint's defaults) to tight.
    tols = (1e-4, 1e-10) if quick else (1e-3, 1e-4, 1e-6, 1e-9, 1e-12)
    model = varint.models.DisorderedKG(n, 4.0, 1)
    x0 = model.initial_block(5 if quick else 21, 0.1, seed=1)
    w0 = seeded_vectors(2 * n, 1, 1, seed=0)[0]
    print(f"\n# {model.name}, one deviation vector, t = {t_end:g}", flush=True)

    def run(t=t_end, outputs=10, **opts):
        r = varint.run(model, x0, "x1", t, deviations=w0, t_out=outputs, progress=False, **opts)
        return {"X1": float(r.exponents[-1, 0]),
                "energy_error": float(np.max(np.abs(r.energy_error))),
                "tau": r.provenance.tau,
                "scheme": (r.provenance.method_options.get("scheme") or {}).get("name"),
                "stepper": r.provenance.method_options.get("stepper")}

    contenders = {("varint", "defaults"): {},
                  ("varint", "scheme='SBAB2C' (the previous default)"): {"scheme": "SBAB2C"}}
    contenders.update({("heyoka", f"tol {tol:g}"): {"tau": 1.0, "method": "taylor", "tol": tol,
                                                   "compact_mode": True} for tol in tols})
    compile_s = {}
    for key, opts in contenders.items():
        t0 = time.perf_counter()
        # Compile (load the cached kernels; for heyoka, build the integrator).
        run(**opts) if key[0] == "varint" else run(t=2.0, outputs=1, **opts)
        compile_s[key] = time.perf_counter() - t0
    tasks = {key: (lambda opts=opts: run(**opts)) for key, opts in contenders.items()}
    best, res = interleaved(tasks, repeats)
    rows = [dict(res[key], peer=key[0], config=key[1], seconds=best[key],
                 warm_up_s=compile_s[key]) for key in contenders]
    front = pareto([(r["seconds"], r["energy_error"]) for r in rows if r["peer"] == "heyoka"])
    equal = []
    for r in rows:
        if r["peer"] != "varint":
            continue
        cost, how = cost_at(front, r["energy_error"])
        equal.append({"varint": r["config"], "energy_error": r["energy_error"],
                      "varint_s": r["seconds"], "heyoka_s": cost, "how": how,
                      "heyoka_over_varint": None if cost is None else cost / r["seconds"]})
    for r in rows:
        print(f"{r['peer']:7s} {r['config']:40s} {r['seconds']:8.3f} s  err "
              f"{r['energy_error']:.2e}  X1 {r['X1']:.6e}", flush=True)
    return {"model": model.name, "n": n, "t_end": t_end, "rows": rows, "equal_energy_error": equal}


def _fpu_heyoka(ta, batch, x0, w0, t_end, e0, scale, model):
    """One heyoka FPU run: the orbit (batch copies of it, each with its own
    deviation vector) to t_end, normalising every EVERY; returns (X1 of the
    first, largest relative energy error at the normalisation times)."""
    d = len(x0)
    st = ta.state
    if batch == 1:
        ta.time = 0.0
        st[:d], st[d:] = x0, w0[0, :, 0]
    else:
        ta.set_time(0.0)
        st[:d], st[d:] = x0[:, None], w0[:batch, :, 0].T
    total, worst = 0.0, 0.0
    n = max(1, round(t_end / EVERY))
    for j in range(1, n + 1):
        ta.propagate_until(t_end * j / n)
        norm = np.sqrt(np.sum(st[d:] ** 2, axis=0))
        st[d:] /= norm
        total += float(np.log(np.atleast_1d(norm)[0]))
        worst = max(worst, float(np.max(np.abs(model.energy(st[:d].T) - e0))))
    return total / t_end, worst / scale


# -- tables -------------------------------------------------------------------------------

def _fmt(v, spec):
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "—"
    return format(v, spec)


def table(title, rows, columns, markdown=False):
    """The text of a table, aligned plain text or a Markdown table under the
    title as a paragraph: columns = [(key, header, width, format)]."""
    if markdown:
        cells = [[_fmt(row.get(k), f) for k, _, _, f in columns] for row in rows]
        lines = ["", "### " + title.strip(), "", "| " + " | ".join(h for _, h, _, _ in columns) + " |",
                 "|" + "|".join(":--" if i == 0 else "--:" for i in range(len(columns))) + "|"]
        lines += ["| " + " | ".join(c) + " |" for c in cells]
        return "\n".join(lines)
    head = " ".join(f"{h:>{w}}" if i else f"{h:<{w}}" for i, (_, h, w, _) in
                    enumerate(columns))
    lines = [title, head, "-" * len(head)]
    for row in rows:
        lines.append(" ".join((f"{_fmt(row.get(k), f):>{w}}" if i else
                               f"{_fmt(row.get(k), f):<{w}}")
                              for i, (k, _, w, f) in enumerate(columns)))
    return "\n".join(lines)


MAP_COLUMNS = [("label", "contender", 58, ""), ("orbits_per_s", "orbits/s", 9, ".0f"),
               ("orbits_per_s_2_threads", "2 threads", 9, ".0f"),
               ("vs_varint_defaults", "× varint", 8, ".2f"), ("agreement", "agree", 7, ".2%"),
               ("compile_s", "compile s", 9, ".2f")]


def report(res, markdown=False):
    """Every table of the run, as aligned text or Markdown."""

    def tab(*args):
        return table(*args, markdown=markdown)

    parts = []
    if "maps" in res:
        mp = res["maps"]
        for ind in mp["thresholds"]:
            th = mp["thresholds"][ind]
            rows = [dict(r, label=f"{r['peer']}: {r['config']}") for r in mp["rows"]
                    if r["indicator"] == ind]
            rule = (f"SALI < {th['value']:g} at a check time" if ind == "sali" else
                    f"{ind.upper()} > {th['value']:.3g} ({th['rule']} of the reference's "
                    "log10 distribution)")
            parts.append(tab(
                f"\n{ind.upper()} map, {mp['orbits']} orbits, t = {mp['t_end']:g}: chaotic if "
                f"{rule}; reference chaotic fraction {mp['chaotic_fraction'][ind]:.1%}",
                rows, MAP_COLUMNS))
        parts.append(tab(
            "\nMaps, varint's defaults against heyoka per thread: against hand-written batch 8 "
            "tol 1e-6 (the issue's target ≥ 3×), and against the fastest heyoka that classifies "
            "at least as well",
            [dict(r, indicator=r["indicator"].upper()) for r in mp["equal_quality"]],
            [("indicator", "map", 5, ""), ("varint_orbits_per_s", "varint/s", 8, ".0f"),
             ("varint_agreement", "agree", 7, ".2%"),
             ("varint_over_hy_b8_1e6", "× hy b8 1e-6", 12, ".2f"),
             ("hy_b8_1e6_agreement", "its agree", 9, ".2%"),
             ("heyoka_equal", "fastest heyoka as good", 28, ""),
             ("heyoka_equal_agreement", "its agree", 9, ".2%"),
             ("varint_over_heyoka_equal", "× it", 6, ".2f")]))
        if mp["variants"]:
            parts.append(tab(
                "\nheyoka driving variants (hand-written, batch 8, tol 1e-9)",
                [dict(r, label=f"{r['indicator'].upper()}: {r['driving']}") for r in mp["variants"]],
                [("label", "variant", 64, ""), ("threads", "threads", 7, "d"),
                 ("orbits_per_s", "orbits/s", 9, ".0f"), ("agreement", "agree", 7, ".2%")]))
    if "spectra" in res:
        for name, sp in res["spectra"].items():
            sample = sp.get("reference_sample")
            columns = [("label", "contender", 44, ""), ("seconds", "seconds", 9, ".3f"),
                       ("X1", "X1", 13, ".6e"), ("X1_error", "|ΔX1|", 9, ".2e")]
            title = f"\nSpectrum {name} to t = {sp['t_end']:g}: X1,ref = {sp['X1_ref']:.6e}"
            if sample:
                columns += [("sample_median", "median X1", 10, ".4f"),
                            ("same_law_p", "KS p", 7, ".2g"), ("same_law", "same law", 8, "")]
                title += (f"; X1 of {sample['n']} nearby orbits by the reference: median "
                          f"{sample['median']:.4f} ({sample['min']:.4f}–{sample['max']:.4f})")
            parts.append(tab(title, [dict(r, label=f"{r['peer']}: {r['config']}")
                                     for r in sp["rows"]], columns))
            parts.append(tab(
                f"\n{name}: heyoka's cost at varint's X1 error"
                if name == "R1" else f"\n{name}: cheapest runs with the reference's X1 "
                "distribution (KS p ≥ 0.01)",
                sp["equal_error"],
                [("varint", "varint", 26, ""), ("X1_error", "|ΔX1|", 9, ".2e"),
                 ("varint_s", "varint s", 9, ".3f"), ("heyoka", "heyoka", 22, ""),
                 ("heyoka_s", "heyoka s", 9, ".3f"), ("how", "how", 27, ""),
                 ("heyoka_over_varint", "hy/varint", 9, ".2f")]))
    if "orbit" in res:
        ob = res["orbit"]
        eq = ob["heyoka_at_varint_error"]
        parts.append(tab(
            f"\nOrbit only, Hénon–Heiles R1, t = {ob['t_end']:g}; varint / C = "
            f"{_fmt(ob['varint_over_C'], '.2f')}; heyoka at varint's energy error: "
            f"{_fmt(eq['ns_per_tau'], '.0f')} ns per τ ({eq['how']}), "
            f"{_fmt(eq['heyoka_over_varint'], '.2f')}× varint",
            [dict(r, label=f"{r['peer']}: {r['config']}") for r in ob["rows"]],
            [("label", "contender", 44, ""), ("ns_per_tau", "ns per τ", 9, ".1f"),
             ("energy_error", "max |ΔH|/H", 10, ".2e")]))
    if "fpu" in res:
        fp = res["fpu"]
        parts.append(tab(
            "\nFPU-β, one deviation vector, ABA864 τ = 0.05: ns per step (CPU time)",
            fp["rows"],
            [("n", "n", 5, "d"), ("varint_ns_per_step", "varint", 10, ".0f"),
             ("numba_ns_per_step", "numba loop", 10, ".0f"),
             ("varint_over_numba", "ratio", 6, ".2f"), ("X1_varint", "X1 varint", 13, ".6e"),
             ("X1_numba", "X1 numba", 13, ".6e"), ("energy_error", "|ΔH|/H", 9, ".1e")]))
        eq = fp["equal_energy_error"]
        parts.append(tab(
            f"\nheyoka at n = {fp['heyoka_n']}, t = {fp['heyoka_t_end']:g}, ns per τ per orbit; "
            "at varint's energy error: " + "; ".join(
                f"{mode} {_fmt(e['ns_per_tau_per_orbit'], '.0f')} ns ({e['how']}, "
                f"{_fmt(e['heyoka_over_varint'], '.2f')}× varint)" for mode, e in eq.items()),
            fp["heyoka"],
            [("config", "heyoka", 24, ""), ("ns_per_tau_per_orbit", "ns per τ", 10, ".0f"),
             ("energy_error", "|ΔH|/H", 9, ".1e"), ("X1", "X1", 13, ".6e"),
             ("compile_s", "compile s", 9, ".2f")]))
    if "lattice" in res:
        lt = res["lattice"]
        parts.append(tab(
            f"\n{lt['model']}, one deviation vector, t = {lt['t_end']:g}: wall seconds (varint's "
            "runs include their pilot)",
            [dict(r, label=f"{r['peer']}: {r['config']}") for r in lt["rows"]],
            [("label", "contender", 50, ""), ("seconds", "seconds", 8, ".3f"),
             ("energy_error", "|ΔH|/H", 9, ".1e"), ("tau", "τ", 7, ".4g"),
             ("X1", "X1", 13, ".6e"), ("warm_up_s", "warm-up s", 9, ".2f")]))
        parts.append(tab(
            "\nheyoka's cost at varint's energy error", lt["equal_energy_error"],
            [("varint", "varint", 40, ""), ("energy_error", "|ΔH|/H", 9, ".1e"),
             ("varint_s", "varint s", 9, ".3f"), ("heyoka_s", "heyoka s", 9, ".3f"),
             ("how", "how", 12, ""), ("heyoka_over_varint", "hy/varint", 9, ".2f")]))
    return "\n".join(parts)


def main(argv=None):
    def extra(parser):
        parser.add_argument("--cases", default=",".join(CASES),
                            help=f"comma-separated subset of {','.join(CASES)}")
        parser.add_argument("--pynamicalsys", action="store_true",
                            help="run pynamicalsys in quick mode too (always in full mode)")
        parser.add_argument("--indicators", default=",".join(INDICATORS),
                            help=f"map indicators, a subset of {','.join(INDICATORS)}")
        parser.add_argument("--grid", type=int, default=None,
                            help="side of the map's grid (default 51; 10 in quick mode)")
        parser.add_argument("--spectra", default="R1,C1",
                            help="paper orbits of the spectrum case, a subset of R1,C1")
        parser.add_argument("--one-thread", action="store_true",
                            help="leave out the maps' two-thread column")
        parser.add_argument("--repeats", type=int, default=None,
                            help=f"repeats per timing (default {REPEATS}; 1 in quick mode)")
        parser.add_argument("--merge", action="store_true",
                            help="replace only the cases run in the stored bench_peers.json, "
                                 "keeping the others (each case records when, on which code "
                                 "and at which load it was measured)")

    args = parse_args(__doc__.split("\n\n")[0], argv, extra)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = sorted(set(cases) - set(CASES))
    if unknown:
        raise ValueError(f"unknown case(s) {', '.join(unknown)}; expected some of "
                         f"{', '.join(CASES)}")
    indicators = tuple(i.strip() for i in args.indicators.split(",") if i.strip())
    if not indicators or set(indicators) - set(INDICATORS):
        raise ValueError(f"--indicators must be a subset of {','.join(INDICATORS)}, got "
                         f"{args.indicators!r}")
    spectra = tuple(i.strip() for i in args.spectra.split(",") if i.strip())
    if not spectra or set(spectra) - {"R1", "C1"}:
        raise ValueError(f"--spectra must be a subset of R1,C1, got {args.spectra!r}")
    if args.grid is not None and args.grid < 2:
        raise ValueError(f"--grid must be an integer >= 2, got {args.grid}")
    repeats = args.repeats or (1 if args.quick else REPEATS)
    numba.set_num_threads(1)
    start = time.perf_counter()
    load = os.getloadavg()[0]
    res = {}
    if "maps" in cases:
        res["maps"] = maps_case(args.quick, repeats, args.pynamicalsys or not args.quick,
                                indicators, args.grid, not args.one_thread)
    if "spectra" in cases:
        res["spectra"] = spectra_case(args.quick, repeats, spectra)
    if "orbit" in cases:
        res["orbit"] = orbit_case(args.quick, repeats)
    if "fpu" in cases:
        res["fpu"] = fpu_case(args.quick, repeats)
    if "lattice" in cases:
        res["lattice"] = lattice_case(args.quick, repeats)
    measured = {"code": CODE, "load": [load, os.getloadavg()[0]], "repeats": repeats,
                "argv": sys.argv[1:] if argv is None else argv,
                "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    fresh = [case for case in CASES if case in res]
    res["measured"] = dict.fromkeys(fresh, measured)
    name = "bench_peers"
    stored = args.out / f"{name}.json"
    if args.merge and stored.exists():
        old = json.loads(stored.read_text())
        for case in CASES:
            if case in old and case not in fresh:
                res[case] = old[case]
                res["measured"][case] = old.get("measured", {}).get(
                    case, {"code": "not recorded (measured before code identity was stored)",
                           "load": old.get("load_average"), "repeats": old.get("repeats"),
                           "argv": old.get("argv")})
    text = report(res)
    print(text)
    res.update(repeats=repeats, quick=args.quick, argv=sys.argv[1:] if argv is None else argv,
               seconds=time.perf_counter() - start,
               load_average=[load, os.getloadavg()[0]], cpus=os.cpu_count(),
               versions=varint.results.package_versions("heyoka"))
    header = (f"# varint against its peers\n\n`python studies/bench_peers.py "
              f"{' '.join(res['argv'])}`: {res['seconds']:.0f} s, {repeats} repeat(s), "
              f"load average {res['load_average'][0]:.1f} → {res['load_average'][1]:.1f} on "
              f"{res['cpus']} CPUs; " + ", ".join(f"{k} {v}" for k, v in res["versions"].items()))
    header += "\n\nMeasured: " + "; ".join(
        f"{case} — " + (f"this run (load {m['load'][0]:.1f} → {m['load'][1]:.1f})"
                        if case in fresh else
                        f"an earlier run (`{' '.join(m.get('argv') or [])}`, code not recorded)")
        for case, m in res["measured"].items())
    (args.out / f"{name}.md").write_text(header + "\n" + report(res, markdown=True) + "\n")
    if "maps" in fresh:
        save_csv(args.out, f"{name}_maps", res["maps"]["rows"], list(res["maps"]["rows"][0]))
    if "spectra" in fresh:
        rows = [r for sp in res["spectra"].values() for r in sp["rows"]]
        save_csv(args.out, f"{name}_spectra", rows, list(rows[0]))
    if "orbit" in fresh:
        save_csv(args.out, f"{name}_orbit", res["orbit"]["rows"], list(res["orbit"]["rows"][0]))
    if "fpu" in fresh:
        save_csv(args.out, f"{name}_fpu", res["fpu"]["rows"], list(res["fpu"]["rows"][0]))
    if "lattice" in fresh:
        save_csv(args.out, f"{name}_lattice", res["lattice"]["rows"],
                 list(res["lattice"]["rows"][0]))
    save_json(args.out, name, res)
    return res


if __name__ == "__main__":
    main()
    sys.exit(0)
