"""The Taylor reference: ``method="taylor"``.

heyoka's adaptive Taylor integrator (Biscani & Izzo 2021) on the orbit and
its variational equations, built from the model's potential written in SymPy
(``model.symbolic()``): heyoka differentiates V itself, for the equations of
motion (paper eq. 6) and, through ``var_ode_sys``, for the variational
equations (eq. 7). Nothing is hand-copied.

Two precisions:

* ``"double"`` — a fast baseline. Blocks of outputs on the τ grid come from
  heyoka's dense output (``propagate_grid``), so the integrator keeps its
  natural step through a block (:mod:`varint.baselines.blocks`).
* ``"extended"`` — the reference: ``numpy.longdouble`` throughout (orbit,
  vectors, QR), restarting every τ. On x86-64 Linux this is the 80-bit x87
  format, 64-bit significand, ε = 2⁻⁶³ ≈ 1.08e-19, 1.6e4 times finer than
  double. Where ``longdouble`` is just double (Windows, macOS on ARM) it is
  refused. At the default tolerance (ε of the type) the error on the paper's
  orbits at t = 100 is ~2e-18 for R1 and ~5e-17 for C1 (measured against
  quadruple precision in the prototype study of the baselines), and
  ``tests/baselines/test_taylor.py`` checks an exact solution to the last
  bit of double after 1000 time units. The RunState holds the rounding to
  double; the long-double state lives in ``state.extra``.

For k < 2N only k vectors are integrated (``var_ode_sys`` with respect to k
of the initial conditions, whose columns are then overwritten), and k = 0
integrates the bare orbit.

A time-dependent V(q, t) is written with heyoka's ``hy.time``, and the
momentum conjugate to time joins the state, ṗ_t = −∂_tV (∂_tV derived by
SymPy), so the extended energy K = H + p_t can be checked; its variations
are integrated (heyoka's layout puts p_t after p) and dropped. Each block
starts at the time its flat state carries (:mod:`varint.baselines.rhs`).
"""

from __future__ import annotations

import math
import threading
from functools import lru_cache

import heyoka as hy
import numba
import numpy as np
import sympy as sp

from varint.kernels.checks import ACC_BIG, ACC_SMALL, orbit_status, tangent_overflow
from varint.protocol import Renorm, Status
from varint._validate import choice, positive_float

from .blocks import BlockPropagator
from .rhs import CLOCK, pack, unpack

__all__ = ["TaylorPropagator", "heyoka_system"]

_FP = {"double": np.float64, "extended": np.longdouble}


#: SymPy functions heyoka has, by their SymPy class.
_FUNCTIONS = {sp.sin: hy.sin, sp.cos: hy.cos, sp.tan: hy.tan, sp.exp: hy.exp, sp.log: hy.log,
              sp.sinh: hy.sinh, sp.cosh: hy.cosh, sp.tanh: hy.tanh, sp.asin: hy.asin,
              sp.acos: hy.acos, sp.atan: hy.atan, sp.asinh: hy.asinh, sp.acosh: hy.acosh,
              sp.atanh: hy.atanh, sp.erf: hy.erf, sp.atan2: hy.atan2}


def _number(value, fp):
    """A SymPy number as a heyoka constant of type ``fp``, correctly rounded."""
    if isinstance(value, sp.Integer):
        return hy.expression(fp(int(value)))
    # Enough digits for any wider type (long double, or heyoka.real128).
    digits = 20 if fp is np.float64 else 40
    return hy.expression(fp(str(sp.N(value, digits))))


def _power(base, n):
    """base**n for an integer n ≥ 1 as a product (by squaring)."""
    result, square = None, base
    while n:
        if n & 1:
            result = square if result is None else result * square
        n >>= 1
        if n:
            square = square * square
    return result


def _to_heyoka(expr, symbols, fp):
    """``expr`` as a heyoka expression; ``symbols`` maps SymPy symbols to
    heyoka variables.

    Written out here rather than with ``heyoka.from_sympy`` for two reasons
    found on the paper's systems: heyoka converts only constants exact in
    double (it refuses 1/3), while we round every constant once in the
    integrator's own precision (so √2 is a long-double √2 in the reference);
    and heyoka's Taylor recursion for ``x**n`` divides by x, so x³ fails
    where x = 0 (the paper's orbits start at x = 0) — integer powers become
    products.
    """
    def convert(e):
        if e in symbols:
            return symbols[e]
        if isinstance(e, (sp.Number, sp.NumberSymbol)):
            return _number(e, fp)
        if isinstance(e, sp.Add):
            return hy.sum([convert(a) for a in e.args])
        if isinstance(e, sp.Mul):
            return hy.prod([convert(a) for a in e.args])
        if isinstance(e, sp.Pow):
            base, exponent = e.args
            if exponent.is_Integer and exponent != 0:
                power = _power(convert(base), abs(int(exponent)))
                return power if exponent > 0 else _number(sp.Integer(1), fp) / power
            if exponent == sp.Rational(1, 2):
                return hy.sqrt(convert(base))
            return convert(base) ** convert(exponent)
        if type(e) in _FUNCTIONS:
            return _FUNCTIONS[type(e)](*[convert(a) for a in e.args])
        raise ValueError(f"method 'taylor' cannot integrate {type(e).__name__} (in {e}); "
                         f"heyoka has: {', '.join(f.__name__ for f in _FUNCTIONS)}")

    return convert(expr)


def heyoka_system(symbolic, fp=np.float64):
    """Hamilton's equations of ``symbolic`` (a
    :class:`~varint.models.SymbolicPotential`, or a
    :class:`~varint.models.hamiltonian.SymbolicHamiltonian` for any H(q, p))
    for heyoka.

    Returns
    -------
    system : list of (variable, expression)
        q̇ = M⁻¹p, ṗ = −∇V (q̇ = ∂H/∂p, ṗ = −∂H/∂q), in state order (q, p);
        for a time-dependent V or H (``symbolic.time``, written as
        ``hy.time``) then ṗ_t = −∂_tV (−∂_tH).
    variables : list of heyoka expressions
        q_0 … q_{N−1}, p_0 … p_{N−1} (and p_t for a time-dependent V).
    """
    n = len(symbolic.q)
    q = [hy.expression(f"q{i}") for i in range(n)]
    p = [hy.expression(f"p{i}") for i in range(n)]
    names = dict(zip(symbolic.q, q, strict=True))
    time = getattr(symbolic, "time", None)
    if time is not None:
        names[time] = hy.time
    if getattr(symbolic, "H", None) is not None:
        return _hamilton_system(symbolic, names, q, p, fp)
    V = _to_heyoka(symbolic.V, names, fp)
    system = [(qi, pi if mi == 1 else _to_heyoka(mi, {}, fp) * pi)
              for qi, pi, mi in zip(q, p, symbolic.inverse_mass, strict=True)]
    system += [(pi, -hy.diff(V, qi)) for qi, pi in zip(q, p, strict=True)]
    if time is None:
        return system, q + p
    pt = hy.expression("p_t")
    system.append((pt, -_to_heyoka(sp.diff(symbolic.V, time), names, fp)))
    return system, q + p + [pt]


def _hamilton_system(symbolic, names, q, p, fp):
    """:func:`heyoka_system` of any H(q, p[, t]): its derivatives taken by
    SymPy, then written for heyoka."""
    names = {**names, **dict(zip(symbolic.p, p, strict=True))}
    H = symbolic.H
    system = [(qi, _to_heyoka(sp.diff(H, ps), names, fp))
              for qi, ps in zip(q, symbolic.p, strict=True)]
    system += [(pi, -_to_heyoka(sp.diff(H, qs), names, fp))
               for pi, qs in zip(p, symbolic.q, strict=True)]
    if symbolic.time is None:
        return system, q + p
    pt = hy.expression("p_t")
    system.append((pt, -_to_heyoka(sp.diff(H, symbolic.time), names, fp)))
    return system, q + p + [pt]


@lru_cache(maxsize=64)
def _integrator(symbolic, precision, tol, compact, k, thread):
    """heyoka's integrator of the orbit and k vectors.

    A cache, not continuation state: every block overwrites the
    integrator's time and state (a Taylor method keeps no history), so
    propagators of the same system share one per thread, and only the first
    pays heyoka's construction (about 20 ms even when the compiled code is
    cached, seconds when it is not).
    """
    fp = _FP[precision]
    system, variables = heyoka_system(symbolic, fp)
    if k:
        # Variations with respect to (q, p) only: δt = 0 and p_t drives nothing.
        args = hy.var_args.vars if k == len(variables) else variables[:k]
        system = hy.var_ode_sys(system, args, order=1)
    kwargs = {"fp_type": fp, "compact_mode": compact}
    if tol is not None:
        kwargs["tol"] = fp(tol)
    return hy.taylor_adaptive(system, np.zeros(len(variables) * (1 + k), dtype=fp), **kwargs)


def _renormalize_extended(W, mode, acc_m, acc_e, r):
    """:func:`varint.kernels.checks.renormalize` in long double (numba has no
    long double): modified Gram–Schmidt or normalisation of the columns, the
    same mantissa/exponent bookkeeping of the stretching factors, which are
    written to ``r``. Returns False if a column is zero or not finite."""
    for j in range(W.shape[1]):
        if mode == Renorm.QR:
            for a in range(j):
                W[:, j] -= (W[:, a] @ W[:, j]) * W[:, a]
        norm = np.sqrt(W[:, j] @ W[:, j])
        if not (0 < norm < np.inf):
            return False
        r[j] = float(norm)
        a = acc_m[j] * r[j]
        if a > ACC_BIG or a < ACC_SMALL:
            a, e = math.frexp(a)
            acc_e[j] += e
        acc_m[j] = a
        W[:, j] /= norm
    return True


class TaylorPropagator(BlockPropagator):
    """Orbits and deviation vectors by heyoka's Taylor integrator.

    Parameters
    ----------
    model : Model
        Must provide ``symbolic()`` (every built-in model does, and every
        model from :func:`varint.models.from_potential`).
    tau : float
        Renormalisation interval (the integrator chooses its own steps).
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    precision : {"double", "extended"}, default "double"
        Floating-point type of the integration (see the module docstring).
    tol : float, optional
        Taylor tolerance; by default the ε of the precision, below which a
        tighter one changes nothing (the error is then round-off).
    compact_mode : bool, optional
        heyoka's compact mode: compiles in a fraction of a second instead of
        seconds for larger systems, runs 1.1–1.7× slower. By default on for
        more than 24 equations (non-compact code for the 3-dof system with
        6 vectors compiles in 6 s in long double, FPU n = 8 with 16 vectors
        in 43 s in double).
    block : int, optional
        Longest block in double precision, in intervals (default: 50 time
        units, over which heyoka's fixed cost per block
        vanishes, ``studies/bench_baselines.py``); always 1 in extended
        precision.
    """

    method = "taylor"
    OPTIONS = {"precision": "double", "tol": None, "compact_mode": None, "block": None}
    BLOCK_SPAN = 50.0

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = self._options(options)
        opts["precision"] = choice(opts["precision"], tuple(_FP), "precision")
        if opts["precision"] == "extended":
            if np.finfo(np.longdouble).eps >= np.finfo(np.float64).eps:
                raise ValueError("precision='extended' needs a long double wider than double; "
                                 "on this platform numpy.longdouble is double")
            if opts["block"] not in (None, 1):
                raise ValueError(f"precision='extended' restarts every tau: block must be 1 or "
                                 f"None, got {opts['block']!r}")
            opts["block"] = 1
        if opts["tol"] is not None:
            opts["tol"] = positive_float(opts["tol"], "tol")
        if opts["compact_mode"] not in (None, True, False):
            raise ValueError(
                f"compact_mode must be True, False or None, got {opts['compact_mode']!r}")
        if not callable(getattr(model, "symbolic", None)):
            raise ValueError(
                f"method 'taylor' needs the potential of {model.name} symbolically "
                "(model.symbolic()); build the model with varint.models.from_potential")
        self._fp = _FP[opts["precision"]]
        self._symbolic = model.symbolic()
        # Shared integrators (see _integrator), looked up once per k.
        self._integrators = {}
        self._setup(model, tau, renorm, opts, accumulator)

    def describe(self):
        d = super().describe()
        d["eps"] = float(np.finfo(self._fp).eps)
        return d

    def versions(self):
        return {"heyoka": hy.__version__, "numba": numba.__version__}

    def _integrator(self, k):
        key = (k, threading.get_ident())
        if key not in self._integrators:
            compact = self.options["compact_mode"]
            if compact is None:
                compact = self.model.dim * (1 + k) > 24
            self._integrators[key] = _integrator(self._symbolic, self.options["precision"],
                                                 self.options["tol"], compact, *key)
        return self._integrators[key]

    def _integrate(self, state, m, y0, n_out):
        d, c = self.model.dim, self._clock
        k = (len(y0) - c) // d - 1
        ta = self._integrator(k)
        grid = np.arange(n_out + 1, dtype=self._fp) * self._fp(self.tau)
        if c:
            # heyoka's layout: (x, p_t, δx, δp_t), from the clock at the end of y0.
            x, W = unpack(y0, d, c)
            t0, pt = y0[-CLOCK], y0[-1]
            y0 = np.concatenate([x, [pt], W.ravel(), np.zeros(k, dtype=y0.dtype)])
            grid = grid + self._fp(t0)
            ta.time = self._fp(t0)
        else:
            ta.time = self._fp(0)
        ta.state[:] = y0
        outcome, _, _, steps, _, states = ta.propagate_grid(grid)
        status = Status.OK
        if outcome != hy.taylor_outcome.time_limit:
            status = (Status.ORBIT_NONFINITE if outcome == hy.taylor_outcome.err_nf_state
                      else Status.INTEGRATOR_FAILED)
        states = states[1:]
        if c:
            states = np.concatenate([states[:, :d], states[:, d + 1:d + 1 + d * k],
                                     grid[1:len(states) + 1, None], states[:, d:d + 1]], axis=1)
        return states, status, {"taylor_steps": steps}

    # -- extended precision: restart every τ from the long-double state -------
    def _prepare(self, state):
        if self._fp is np.float64:
            return super()._prepare(state)
        if "taylor_x" not in state.extra:
            state.extra["taylor_x"] = state.x.astype(np.longdouble)
            state.extra["taylor_W"] = state.W.astype(np.longdouble)
            if self._clock:
                state.extra["taylor_pt"] = state.time_momentum().astype(np.longdouble)

    def _advance_orbit(self, state, m, n):
        if self._fp is np.float64:
            return super()._advance_orbit(state, m, n)
        d, c = state.x.shape[1], self._clock
        x, W = state.extra["taylor_x"][m], state.extra["taylor_W"][m]
        pt = state.extra["taylor_pt"][m:m + 1] if c else None
        accumulate, aux, flow = self._accumulator(state, m)
        for done in range(n):
            # The time in long double, from the integer step.
            clock = ((self._fp(state.step + done) * self._fp(self.tau), pt[0]) if c else ())
            ys, status, counts = self._integrate(state, m, pack(x, W, clock=clock), 1)
            state.add_counts(**counts)
            if len(ys):
                x1, W1 = unpack(ys[0], d, c)
                x[:], W[:] = x1, W1
                if c:
                    pt[0] = ys[0][-1]
                    state.time_momentum()[m] = float(pt[0])
                status = self._check(x, W, state.acc_m[m], state.acc_e[m], accumulate, aux, flow,
                                     (state.step + done + 1) * self.tau)
            state.x[m], state.W[m] = x, W
            if status != Status.OK:
                return done, status
        return n, Status.OK

    def _check(self, x, W, acc_m, acc_e, accumulate, aux, flow, t):
        """The end of an interval in long double: the stepping skeleton's
        contract (:mod:`varint.kernels.interval`), which numba cannot
        compile for long double, written out here — the checks of
        :mod:`varint.kernels.checks` on the state rounded to double, the
        renormalisation in long double, and the accumulator's update (with
        the flow if ``flow``)."""
        xd = x.astype(np.float64)
        status = orbit_status(xd, xd.shape[0] // 2, self._escape_r2)
        if status != Status.OK:
            return status
        if self._mode == Renorm.NONE:
            return Status.TANGENT_OVERFLOW if tangent_overflow(W.astype(np.float64)) else Status.OK
        r = np.empty(W.shape[1])
        if not _renormalize_extended(W, self._mode, acc_m, acc_e, r):
            return Status.TANGENT_DEGENERATE
        if aux.shape[0]:
            n = self.model.n_dof
            velocity = np.empty(2 * n if flow else 0)
            if flow:
                velocity[:n] = self.model.inverse_mass * xd[n:]
                velocity[n:] = -self.model.gradient(xd[:n], t)
            accumulate(aux, r, xd, W.astype(np.float64), velocity, t)
        return Status.OK
