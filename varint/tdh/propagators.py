"""The TDH methods as propagators: ``method="tdhcc"``, ``"tdhes"``,
``"tdheps"`` (rules of :class:`varint.protocol.Propagator`).

All three integrate the orbit with a splitting scheme (``scheme=``, the
paper's SBAB2C by default) and the deviation vectors with an approximation
of the tangent dynamics Hamiltonian (TDH) that knows the orbit only at the
grid times t_i = iΔt. The order of the tangent error of each method, for a
fixed final time T and τ → 0, is derived in each class's docstring and
returned by :attr:`tangent_order`; tests/test_tdh.py measures it.

Unlike the TM method, none of them produces the derivative of the numerical
orbit map: their tangent map is that of a nearby non-autonomous linear
system. For a regular orbit this matters more than the order suggests. The
tangent map along a torus shears (deviations grow linearly), and a small
perturbation of such a parabolic map can move its eigenvalues off the unit
circle by O(√ε) for a perturbation ε per unit time; the vectors then grow
exponentially and X1 levels off (the paper's Fig. 2; :mod:`varint.departure`
finds where). Measured on R1 the level is ≈ 0.018 τ for TDHcc and TDHes
(τ = 0.025–0.2) and ≈ 0.030 τ² for TDHeps (τ = 0.05–0.2). That fits
ε ∝ τ⁴ for TDHeps, and ε ∝ τ² for TDHcc/TDHes if their O(τ) error
(sampling D²V at t_i instead of the interval's middle) acts to leading
order like a time shift along the torus, which does no such harm. Whether
the eigenvalues leave the circle depends on the sign of the perturbation:
with an SBAB2 orbit under the SBAB2C TDHeps, X1 kept falling to t = 3e5.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy  # type: ignore[import-untyped]

from .._validate import choice
from ..codegen.expressions import symbolic_fits
from ..codegen.stepper import symbolic_stepper
from ..kernels import tm as K
from ..kernels.interval import Call, no_accumulator, use_parallel
from ..methods.options import method_options
from ..models.henon_heiles import HenonHeiles
from ..protocol import COUNTERS, STATUS_OK, Renorm
from ..schemes import DEFAULT_SCHEME, DRIFT, get_scheme, registered, stage_arrays, stage_times
from . import _kernels as TK
from .frozen import henon_heiles_eig

__all__ = ["TDHccPropagator", "TDHesPropagator", "TDHepsPropagator", "eps_grid"]

#: Largest number of orbit steps per interval TDHeps accepts (the denominator
#: of the kick times of its scheme, in units of τ).
MAX_GRID = 8


def eps_grid(scheme):
    """Where the kicks of ``scheme`` need the orbit, in orbit steps.

    TDHeps (paper Sect. V.B.2, eqs. 38–40 of the LaTeX source) can apply a
    kick of the extended-phase-space TDH only at a time where the orbit is
    known. A kick preceded by drifts of total length cτ needs q(t_i + cτ),
    so the scheme is usable iff every such c is a multiple of 1/m for a
    small integer m: the orbit is then integrated with Δt = τ/m.

    Parameters
    ----------
    scheme : str or SplittingScheme

    Returns
    -------
    m : int or None
        Orbit steps per interval τ (1 for SBAB1, 2 for SBAB2 and SABA1),
        or None if some kick falls off every grid with m ≤ ``MAX_GRID``.
    index : ndarray of int64
        For each stage of :func:`varint.schemes.stage_arrays`, the grid
        point 0..m of its kick (0 for drifts); empty when ``m`` is None.
    """
    kinds, h, _ = stage_arrays(get_scheme(scheme, n_parts=2), 1.0)
    times, t = [], 0.0
    for kind, c in zip(kinds, h, strict=True):
        times.append(t)
        if kind == DRIFT:
            t += c
    times = np.array(times)
    kicks = kinds != DRIFT
    for m in range(1, MAX_GRID + 1):
        grid = np.round(times * m)
        if np.all(np.abs(times[kicks] * m - grid[kicks]) < 1e-12):
            return m, np.where(kicks, grid, 0).astype(np.int64)
    return None, np.zeros(0, dtype=np.int64)


def _analytic_eig(model):
    """The closed-form eigensolver of ``model``'s frozen TDH: the paper's
    (A.10) for Hénon–Heiles with unit masses, else None (LAPACK's only)."""
    if isinstance(model, HenonHeiles) and np.all(model.inverse_mass == 1.0):
        return henon_heiles_eig
    return None


def _eps_schemes():
    return [s.name for s in registered(2) if eps_grid(s)[0] is not None]


class _TDHPropagator:
    """What the three TDH propagators share: settings, the orbit's stage
    tables, and :meth:`advance` over the compiled stepper."""

    method = ""
    _mode: int | None = None
    #: Options every TDH method takes; subclasses add their own.
    OPTIONS: tuple[str, ...] = ("scheme", "parallel")
    #: What the accuracy verdict, measured on the orbit, does not check.
    TANGENT_NOTE = ("the verdict checks the orbit only: the TDH methods integrate the "
                    "deviation vectors apart from it, with an error of order 1 (TDHcc, TDHes) "
                    "or 2-4 (TDHeps) in tau that the energy does not show; "
                    "varint.departure measures it")

    def __init__(self, model, tau, renorm, accumulator, options, n_sub):
        self.model = model
        self.tau = float(tau)
        self.renorm = Renorm.parse(renorm)
        self.accumulator = accumulator
        self.parallel = options.get("parallel")
        self.scheme = get_scheme(options.get("scheme", DEFAULT_SCHEME), n_parts=2)
        self.n_sub = int(n_sub)
        #: The orbit's integration step Δt (τ, or τ/m for TDHeps).
        self.orbit_step = self.tau / self.n_sub
        self._kinds, self._h, self._hc = stage_arrays(self.scheme, self.orbit_step)
        # A time-dependent V: the time of each of the orbit's stages.
        self._ctime = stage_times(self.scheme) if model.time_dependent else np.empty(0)
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2
        # Defaults for the tangent part; subclasses overwrite what they use.
        self._tkinds, self._th, self._thc = (np.zeros(0, dtype=np.int64), np.zeros(0),
                                             np.zeros(0))
        self._tidx = np.zeros(0, dtype=np.int64)
        self._need = np.zeros(self.n_sub + 1, dtype=np.bool_)
        self._need[0] = True
        self._analytic = False

    def describe(self):
        # tangent_order: order p of the tangent error, ‖w − w_exact‖ = O(τ^p)
        # at a fixed final time (each method derives its own).
        return {"scheme": self.scheme.describe(), "orbit_step": self.orbit_step,
                "tangent_order": self.tangent_order}

    def versions(self):
        return {"numba": numba.__version__}

    def _orbit_stepper(self):
        """The generated TM stepper of the orbit (k = 0) when the model has
        one, so the orbit is the TM method's own; None for the generic one."""
        if not hasattr(self, "_generated"):
            self._generated = None
            if symbolic_fits(self.model, 0):
                corrected = (self._hc != 0.0) & (self._kinds != DRIFT)
                self._generated = symbolic_stepper(self.model, self._kinds, corrected, 0)
        return self._generated

    def batch_kernel(self, k, parallel):
        """The compiled batch stepper for ``k`` vectors
        (:func:`varint.tdh._kernels.batch_kernel`): one for the three
        methods and both eigensolvers, which the setup of each call
        chooses."""
        model, acc = self.model, self.accumulator
        update, flow = (no_accumulator, False) if acc is None else (acc.update, acc.needs_flow)
        return TK.batch_kernel(model.n_dof, k, model.bandwidth, parallel, K.model_kernels(model),
                               _analytic_eig(model), update, flow, self._orbit_stepper(),
                               model.time_dependent)

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` intervals τ."""
        m = state.n_orbits
        model = self.model
        acc = self.accumulator
        aux = np.empty((m, 0, 0)) if acc is None else state.extra[acc.key]
        time = model.time_dependent
        kernel = self.batch_kernel(state.k, use_parallel(self.parallel, m))
        counters = np.zeros((m, len(TK.COUNTERS)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        was_active = state.status == STATUS_OK
        pt = state.time_momentum()[:, None] if time else np.empty((m, 0))
        kernel(TK.TDHOrbit(state.x, state.W, state.acc_m, state.acc_e, aux, counters, pt),
               TK.TDHSetup(self._kinds, self._h, self._hc, self._ctime, self.n_sub, self._tkinds,
                           self._th, self._thc, self._tidx, self._need, model.inverse_mass,
                           model.params, model.bandwidth, self._mode == TK.ES, self._analytic),
               Call(int(n), state.step, self.tau, int(self.renorm), self._escape_r2),
               state.status, done)
        state.after_kernel(n, was_active, done, counters,
                           TK.COUNTERS if self._mode == TK.ES else COUNTERS)


class TDHccPropagator(_TDHPropagator):
    """TDHcc: the TDH with piecewise constant coefficients, integrated by a
    splitting scheme (paper Sect. V.B.1).

    Over [t_i, t_i + τ) the Hessian is frozen at the orbit's q(t_i), and
    H_V = ½δpᵀM⁻¹δp + ½δqᵀD²V(q(t_i))δq is integrated by ``substeps``
    steps of ``tangent_scheme``: drifts δq += hM⁻¹δp, kicks
    δp −= h D²V δq, and for a corrected scheme the corrector of
    C̃ = δqᵀD²V M⁻¹D²V δq. The orbit takes one step Δt = τ of ``scheme``.

    Order of the tangent error: **1**. Freezing replaces D²V(q(t)) by
    D²V(q(t_i)) = D²V(q(t)) + O(t − t_i) on each interval; the variational
    equations' solution over a fixed T then carries the error
    Σ_i O(τ²) = O(τ) (a left-endpoint rule). The inner scheme adds
    O((τ/substeps)^r) with r its order (4 for SBAB2C on this quadratic
    Hamiltonian) and the orbit O(τ^p) with p the orbit scheme's order:
    both are of higher order. As ``substeps`` grows, TDHcc tends to TDHes.

    Parameters
    ----------
    model : Model
    tau : float
        Renormalisation interval, equal to the orbit's step Δt.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    scheme : str or SplittingScheme, default "SBAB2C"
        Scheme of the orbit.
    tangent_scheme : str or SplittingScheme, optional
        Scheme of the frozen TDH; the orbit's by default (the paper).
    substeps : int, default 1
        Steps of ``tangent_scheme`` per interval.
    parallel : bool, optional
        Orbits of a batch in parallel (as for ``"tm"``).
    """

    method = "tdhcc"
    _mode = TK.CC

    OPTIONS = _TDHPropagator.OPTIONS + ("tangent_scheme", "substeps")

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        options = method_options(self.method, options, self.OPTIONS)
        super().__init__(model, tau, renorm, accumulator, options, n_sub=1)
        substeps = options.get("substeps", 1)
        tangent_scheme = options.get("tangent_scheme")
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) \
                or substeps < 1:
            raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
        self.substeps = int(substeps)
        self.tangent_scheme = self.scheme if tangent_scheme is None else get_scheme(
            tangent_scheme, n_parts=2)
        tables = stage_arrays(self.tangent_scheme, self.tau / self.substeps)
        self._tkinds, self._th, self._thc = (np.tile(a, self.substeps) for a in tables)
        self._tidx = np.zeros(len(self._tkinds), dtype=np.int64)

    @property
    def tangent_order(self):
        return 1

    def describe(self):
        return dict(super().describe(), tangent_scheme=self.tangent_scheme.describe(),
                    substeps=self.substeps)


class TDHesPropagator(_TDHPropagator):
    """TDHes: the TDH with piecewise constant coefficients, solved exactly
    (paper Sect. V.B.1, eqs. 28–29 of the LaTeX source).

    Over [t_i, t_i + τ) the Hessian is frozen at q(t_i) and the quadratic
    Hamiltonian is solved through the eigen-decomposition
    M^{-1/2}D²V M^{-1/2} = QΛQᵀ as N uncoupled oscillating (λ > 0), free
    (λ = 0) or hyperbolic (λ < 0) modes (:mod:`varint.tdh.frozen`). The
    orbit takes one step Δt = τ of ``scheme``.

    Order of the tangent error: **1**, from freezing (see
    :class:`TDHccPropagator`); the frozen flow itself is exact.

    Parameters
    ----------
    model : Model
    tau : float
        Renormalisation interval, equal to the orbit's step Δt.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    scheme : str or SplittingScheme, default "SBAB2C"
        Scheme of the orbit.
    eigensolver : {"lapack", "analytic"}, default "lapack"
        LAPACK's symmetric eigensolver (any N; one call per interval and
        orbit, about 0.4 µs for N = 2), or for :class:`HenonHeiles` the
        paper's closed-form transformation (eq. A.10).
    parallel : bool, optional
    """

    method = "tdhes"
    _mode = TK.ES

    OPTIONS = _TDHPropagator.OPTIONS + ("eigensolver",)

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        options = method_options(self.method, options, self.OPTIONS)
        super().__init__(model, tau, renorm, accumulator, options, n_sub=1)
        self.eigensolver = choice(options.get("eigensolver", "lapack"), ("lapack", "analytic"),
                                  "eigensolver")
        if self.eigensolver == "analytic":
            if _analytic_eig(model) is None:
                raise ValueError(
                    f"eigensolver='analytic' is the paper's transformation (A.10) for the "
                    f"Hénon–Heiles model with unit masses; got {model!r}: use 'lapack'")
            self._analytic = True

    @property
    def tangent_order(self):
        return 1

    def describe(self):
        return dict(super().describe(), eigensolver=self.eigensolver)

    def versions(self):
        # numba's eigh calls the LAPACK that SciPy ships.
        versions = super().versions()
        if self.eigensolver == "lapack":
            versions["scipy"] = scipy.__version__
        return versions


class TDHepsPropagator(_TDHPropagator):
    """TDHeps: the TDH in the extended phase space, with time as a
    coordinate (paper Sect. V.B.2, eqs. 30–40 of the LaTeX source).

    H̃_V = ½δpᵀM⁻¹δp + δp_t + ½δqᵀD²V(q(t))δq splits into
    Ã = ½δpᵀM⁻¹δp + δp_t, whose flow drifts δq and advances t, and
    B̃ = ½δqᵀD²V(q(t))δq, whose flow kicks δp with D²V at the current t; the
    corrector C̃ = {B̃, {B̃, Ã}} = δqᵀD²V M⁻¹D²V δq acts at the same times.
    ``tangent_scheme`` integrates H̃_V over τ; every kick must fall on the
    orbit's grid (:func:`eps_grid`), so the orbit takes m steps Δt = τ/m of
    ``scheme`` per interval: m = 2 for SBAB2C (the paper's τ = 2Δt, using
    q(t_i), q(t_i + Δt), q(t_i + 2Δt) as in eqs. A.15–A.18) and m = 1 for
    the leapfrog variant SBAB1 (τ = Δt). Schemes whose kicks fall between
    grid points (SABA2, SBAB3, ABA864, …) are refused.

    Order of the tangent error: **min(r, p)**, with r the order of
    ``tangent_scheme`` and p that of ``scheme``. H̃_V is an autonomous
    Hamiltonian split into two integrable parts, so a splitting scheme
    integrates it with its usual order: SBAB2C is O(τ⁴) (the corrector
    removes the τ²ε² term, and C̃ is exactly {B̃, {B̃, Ã}} since B̃ does not
    depend on δp_t) and SBAB1 O(τ²). The coefficients D²V(q(t_i + jΔt)) come
    from the orbit, whose error is O(Δt^p). So the paper's SBAB2C/SBAB2C
    pair is of order 4 and the leapfrog variant of order 2.

    Parameters
    ----------
    model : Model
    tau : float
        Renormalisation interval, the step of ``tangent_scheme``.
    renorm : Renorm
    accumulator : Accumulator, optional
        Updated after every interval (:class:`varint.protocol.Accumulator`).
    scheme : str or SplittingScheme, default "SBAB2C"
        Scheme of the orbit.
    tangent_scheme : str or SplittingScheme, optional
        Scheme of the extended-phase-space TDH; the orbit's by default (the
        paper). Usable: those :func:`eps_grid` accepts (SABA1, SABA1C,
        SBAB1, SBAB1C, SBAB2, SBAB2C among the registered ones).
    parallel : bool, optional

    Raises
    ------
    ValueError
        For a ``tangent_scheme`` that needs the orbit off the grid.
    """

    method = "tdheps"
    _mode = TK.EPS

    OPTIONS = _TDHPropagator.OPTIONS + ("tangent_scheme",)

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        options = method_options(self.method, options, self.OPTIONS)
        scheme = options.get("scheme", DEFAULT_SCHEME)
        tangent_scheme = options.get("tangent_scheme")
        tangent = get_scheme(scheme if tangent_scheme is None else tangent_scheme, n_parts=2)
        m, index = eps_grid(tangent)
        if m is None:
            raise ValueError(
                f"TDHeps cannot integrate the tangent dynamics with {tangent.name}: its kicks "
                f"need the orbit between the grid points t_i + jτ/m (m ≤ {MAX_GRID}); "
                f"pass tangent_scheme= one of: {', '.join(_eps_schemes())}")
        super().__init__(model, tau, renorm, accumulator, options, n_sub=m)
        self.tangent_scheme = tangent
        self._tkinds, self._th, self._thc = stage_arrays(tangent, self.tau)
        self._tidx = index
        self._need = np.zeros(m + 1, dtype=np.bool_)
        self._need[np.unique(index[self._tkinds != DRIFT])] = True

    @property
    def tangent_order(self):
        return min(self.tangent_scheme.order, self.scheme.order)

    def describe(self):
        return dict(super().describe(), tangent_scheme=self.tangent_scheme.describe())
