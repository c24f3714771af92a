"""The tangent map method on models split into k ≥ 2 parts: what
``method="tm"`` runs for a model that declares its parts
(:class:`varint.models.lattice.Parts`; the lattices of
:mod:`varint.models`).

Any two-part scheme of :data:`varint.SCHEMES` (drift → the first part of the
model's two-part split, kick → the second) or composition of
:data:`varint.schemes.SCHEMES` over k parts runs through the model's
fused part flows (:mod:`varint.kernels.parts`). Corrector schemes (SABA_nC,
SBAB_nC) need the corrector C = {B,{B,A}} = |∇V|² and its Hessian; the
lattices have no corrector part, so they run through the generic stepper
(:mod:`varint.methods.tm`) with the band kernels when the model has them
(chains with fixed ends), and are refused otherwise. :func:`runs_parts`
decides, and :func:`varint.methods.make_propagator` asks it.
"""

from __future__ import annotations

import numba
import numpy as np

from .._validate import steps_arguments
from ..codegen.expressions import symbolic_fits
from ..kernels import parts as K
from ..kernels.interval import Call, no_accumulator, use_parallel
from ..protocol import REASONS, STATUS_OK, Renorm, Status
from ..schemes import CORRECTOR, CompositionScheme, part_stages, scheme_word
from .fresh_parts_run import FreshPartsRun
from .options import method_options

__all__ = ["PartsPropagator", "parts_steps", "runs_parts", "generated_rotating"]


def _scheme(model, scheme):
    return model.parts.resolve(scheme, model.name)


def runs_parts(model, scheme=None):
    """Whether ``method="tm"`` runs ``model`` with ``scheme`` (None: the
    default) through the part stepper: the model declares parts, and the
    scheme is a k-part composition or a two-part scheme without corrector
    (except on a chain split as T + V or a rotating frame's A + V that gets
    a generated stepper, see :func:`varint.codegen.expressions.symbolic_fits`
    and :func:`generated_rotating`), or the model has no band kernels for
    the generic stepper."""
    parts = getattr(model, "parts", None)
    if parts is None:
        return False
    if scheme is None and parts.default_scheme is None:
        return False
    s = _scheme(model, scheme)
    if isinstance(s, CompositionScheme):
        return True
    if generated_rotating(model) and (s.corrector is None
                                      or getattr(model, "extra_force", None) is None):
        # A rotating frame's A + V with a generated stepper (the drift A's
        # exact flow, varint.codegen.tm): the CR3BP's map step took 30x a
        # generated potential's through the part flows, 4.6x on its own
        # generated stepper (studies/map_steps.py). A corrector of a model
        # with an extra force (the bar) would need its third derivatives:
        # the part stepper refuses it with its reason.
        return False
    if not getattr(model, "band_kernels", True):
        return True
    if s.corrector is not None:
        return False
    # A two-part scheme on a chain split as T + V is the TM method's own
    # splitting: a small chain with a symbolic potential takes the stepper
    # generated for it, ~5x faster than the part flows' loops over sites
    # (FPU-beta N = 8, SBAB2: 23 against 174 ns per step).
    return not (parts.splits.get(2) == ("T", "V") and symbolic_fits(model, 0))


def generated_rotating(model):
    """Whether ``model`` is H = A + V(q) with A a rotating frame's or a
    uniform magnetic field's solvable quadratic
    (:class:`~varint.models.hamiltonian.IntegrableHamiltonian`) that gets a
    generated stepper (:func:`~varint.codegen.expressions.symbolic_fits`)
    for every number of vectors up to 2N: then ``method="tm"`` runs its
    two-part schemes, correctors included, on that stepper (one orbit and
    SIMD lanes) instead of the part flows."""
    return getattr(model, "structure", None) == "integrable" and symbolic_fits(model, model.dim)


class PartsPropagator:
    """Advance orbits and deviation vectors through a model's part flows.

    Parameters
    ----------
    model : LatticeModel
        A model with ``parts``.
    tau : float
        Step, which is also the renormalisation interval.
    renorm : Renorm
    accumulator : Accumulator, optional
    scheme : str, SplittingScheme or CompositionScheme, optional
        By default the model's (``model.parts.default_scheme``).
    parallel : bool, optional
        Run the orbits of a batch on all cores (threads over slices of
        them, :func:`varint.threads.orbits_in_threads`); by
        default when there is more than one orbit and more than one thread.

    Raises
    ------
    ValueError
        If the scheme does not fit the model's splits (e.g. a three-part
        composition on H = T + V) or needs a corrector part the model does
        not have.
    """

    method = "tm"
    OPTIONS = ("scheme", "parallel")
    #: The vectors are renormalised at every step, never held raw between
    #: renormalisations (:class:`varint.rerun.ShortCall` reads it).
    sparse = 0

    def __init__(self, model, tau, renorm, accumulator=None, **options):
        opts = method_options(self.method, options, self.OPTIONS)
        parts = getattr(model, "parts", None)
        if parts is None:
            raise ValueError(f"{model.name} declares no parts; the part stepper needs a model "
                             "such as varint.models.DisorderedKG, FPUT or DDNLS")
        self.model = model
        self.tau = float(tau)
        self.scheme = _scheme(model, opts.get("scheme"))
        self.renorm = Renorm.parse(renorm)
        self.parallel = opts.get("parallel")
        self.accumulator = accumulator
        self._parts, self._h, self._par, self._n_work = _tables(model, self.scheme, self.tau)
        r = model.escape_radius
        self._escape_r2 = np.inf if r is None else float(r) ** 2

    def describe(self):
        d = {"scheme": self.scheme.describe(), "stepper": "parts"}
        return d

    def versions(self):
        return {"numba": numba.__version__}

    def advance(self, state, n):
        """Advance every active orbit of ``state`` by ``n`` steps."""
        m, d = state.x.shape
        self._advance(state, int(n), _NO_CHECKS, np.empty((m, 0, d)), np.empty((m, 0)))

    def takes_checks(self):
        """Whether :meth:`advance_checks` runs this propagator's steps: the
        part stepper's (a subclass that runs another stepper, such as
        :class:`~varint.methods.general.GeneralPropagator` with Tao's
        method, builds no part tables)."""
        return hasattr(self, "_n_work")

    def runs_fresh(self, m, k):
        """Whether :meth:`fresh_run` can run ``m`` orbits with ``k`` vectors:
        wherever the part stepper runs them (not Tao's method of a
        :class:`~varint.methods.general.GeneralPropagator`, which carries a
        second copy of phase space in the run state), for an H without time
        (:class:`varint.rerun.ShortCall` runs no time-dependent model)."""
        return self.takes_checks() and not self.model.parts.timed

    def fresh_run(self, m, k, outs, aux0):
        """A :class:`~varint.methods.fresh_parts_run.FreshPartsRun`: orbits
        started at step 0 advanced to each output step ``outs`` (int64,
        increasing) by the stepper :meth:`advance` runs, copied there, with
        one thread's buffers kept between runs (a prepared run's short
        call, :class:`varint.rerun.ShortCall`); ``aux0`` (M, k, c) is the
        accumulator's start. Only where :meth:`runs_fresh`."""
        parts = self.model.parts
        kernel = self._kernel(m, k)
        setup = K.CheckedPartsSetup(self._parts, self._h, self._par, self._n_work, _NO_CHECKS)
        return FreshPartsRun(kernel, setup, self.tau, int(self.renorm), self._escape_r2,
                             np.asarray(outs, dtype=np.int64), (m, self.model.dim, k), aux0,
                             None if self.accumulator is None else self.accumulator.key,
                             ("steps", *self._count_names(parts)))

    def _kernel(self, m, k):
        """The part stepper of ``m`` orbits with ``k`` vectors (checks
        compiled in, none asked by a run)."""
        parts, acc = self.model.parts, self.accumulator
        update, flow = (no_accumulator, False) if acc is None else (acc.update, acc.needs_flow)
        return K.parts_batch(parts.applying(np.unique(self._parts)), parts.field, k,
                             use_parallel(self.parallel, m), update, flow, parts.timed, True)

    @staticmethod
    def _count_names(parts):
        return tuple(f"flow_{name}" for name in parts.names)

    def advance_checks(self, state, checks):
        """Advance every active orbit of ``state`` to the step ``checks[-1]``
        in one call, copying it at the steps ``checks`` (int64, increasing,
        after ``state.step``): a pilot's checks (:mod:`varint.stepsize`),
        bitwise the states of an :meth:`advance` to each check in turn.

        Returns
        -------
        x : ndarray, shape (C, M, 2N)
            The orbits at the checks; NaN where an orbit had stopped.
        p_t : ndarray, shape (C, M), or None
            Their momenta conjugate to time (a time-dependent H), else None.
        """
        m, d = state.x.shape
        sx, spt = np.full((m, len(checks), d), np.nan), np.full((m, len(checks)), np.nan)
        self._advance(state, int(checks[-1] - state.step), checks, sx, spt)
        return sx.transpose(1, 0, 2), spt.T if self.model.parts.timed else None

    def _advance(self, state, n, checks, sx, spt):
        """:meth:`advance` by ``n`` steps, copying the orbits at ``checks``
        to ``sx`` (M, C, 2N) and their time momenta to ``spt`` (M, C): one
        compiled stepper for runs (no checks) and pilots."""
        m = state.n_orbits
        parts = self.model.parts
        acc = self.accumulator
        kernel = self._kernel(m, state.k)
        aux = np.empty((m, 0, 0)) if acc is None else state.extra[acc.key]
        counters = np.zeros((m, len(parts.names)), dtype=np.int64)
        done = np.zeros(m, dtype=np.int64)
        at = np.zeros((m, 1), dtype=np.int64)
        was_active = state.status == STATUS_OK
        record = (K.TimedCheckedPartsOrbit(state.x, state.W, state.acc_m, state.acc_e, aux,
                                           counters, state.time_momentum()[:, None], sx, spt, at)
                  if parts.timed else
                  K.CheckedPartsOrbit(state.x, state.W, state.acc_m, state.acc_e, aux, counters,
                                      sx, at))
        kernel(record,
               K.CheckedPartsSetup(self._parts, self._h, self._par, self._n_work, checks),
               Call(n, state.step, self.tau, int(self.renorm), self._escape_r2),
               state.status, done)
        state.after_kernel(n, was_active, done, counters, self._count_names(parts))


#: The check steps of a run's call (none).
_NO_CHECKS = np.zeros(0, dtype=np.int64)


def _tables(model, scheme, tau):
    """Stage tables (part index and length of every flow), parameters and
    scratch size of one step of ``scheme`` on ``model``."""
    parts = model.parts
    word = scheme_word(scheme)
    has_corrector = any(slot == CORRECTOR for slot, _, _ in word)
    if has_corrector:
        raise ValueError(f"scheme {scheme.name!r} needs the corrector flow of C = {{B,{{B,A}}}}, "
                         f"which {model.name} does not provide through its parts; use a "
                         "scheme without corrector (ABA864, SABA2, SBAB2, …), or a chain with "
                         "fixed ends, whose band kernels run correctors in the generic stepper")
    n_parts = scheme.n_parts if isinstance(scheme, CompositionScheme) else 2
    slots = parts.slots(n_parts)
    kinds, h = part_stages(scheme, tau, slots)
    par, n_work = parts.params(n_parts)
    return kinds, h, np.ascontiguousarray(par, dtype=np.float64), int(n_work)


def parts_steps(model, x, W=None, tau=0.05, n_steps=1, scheme=None):
    """Low-level: :func:`varint.methods.tm.tangent_map_steps` through the
    model's part flows — ``n_steps`` steps of the numerical map S and its
    tangent map TS, without renormalisation; τ may be negative.

    Parameters
    ----------
    model : LatticeModel
    x, W, tau, n_steps
        As :func:`~varint.methods.tm.tangent_map_steps`, which also gives
        the returned ``(x, W)`` and the FloatingPointError of a failed map.
    scheme : str, SplittingScheme or CompositionScheme, optional
        The model's default scheme when None.
    """
    x, W = steps_arguments(model, x, W, tau)
    W = np.ascontiguousarray(W[None])
    k = W.shape[2]
    kinds, h, par, n_work = _tables(model, _scheme(model, scheme), float(tau))
    status = np.zeros(1, dtype=np.int64)
    done = np.zeros(1, dtype=np.int64)
    timed = model.parts.timed
    kernel = K.parts_batch(model.parts.applying(np.unique(kinds)), model.parts.field, k, False,
                           time=timed)
    fields = (x, W, np.ones((1, k)), np.zeros((1, k), dtype=np.int64), np.empty((1, 0, 0)),
              np.zeros((1, len(model.parts.names)), dtype=np.int64))
    # A time-dependent H starts at t = 0 with p_t = 0.
    kernel(K.TimedPartsOrbit(*fields, np.zeros((1, 1))) if timed else K.PartsOrbit(*fields),
           K.PartsSetup(kinds, h, par, n_work), Call(int(n_steps), 0, float(tau), int(Renorm.NONE),
                                                      np.inf), status, done)
    if status[0] != STATUS_OK:
        raise FloatingPointError(f"the map failed after {done[0]} steps: "
                                 f"{REASONS.get(Status(status[0]), status[0])}")
    return x[0], W[0]
