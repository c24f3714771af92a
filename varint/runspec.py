"""What a run is, checked once: :class:`RunSpec` and :func:`specify`.

Every workflow that integrates — one run (:func:`varint.run.prepare`), each
chunk of a chaos map (:func:`varint.chaos_map`), each realisation of an
ensemble (:func:`varint.ensemble`) — starts from the same specification:
the model (with the call's escape radius), the initial states and the
energies and scales their errors are measured against, the indicator and
its configured options, the method and its options, the times, the seed and
the energy tolerance. :func:`specify` checks the arguments of a call and
builds it before any work; a :class:`~varint.run.Run` executes it, and a
map hands the same specification to each chunk (:meth:`RunSpec.for_orbits`)
instead of passing the arguments on to be checked again.

τ is the one part a specification may leave open (``tau=None``): the run
(or the map, for all its chunks) chooses it with a pilot
(:mod:`varint.stepsize`) and records the choice; :meth:`RunSpec.with_step`
fixes it, with its output steps.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _validate as check
from . import accuracy, identity, stepsize
from .files import digest
from .indicators import Indicator, resolve
from .methods import METHODS
from .results import package_versions
from .state import output_steps

__all__ = ["RunSpec", "specify", "specify_call", "check_seed", "described", "DEFAULT_TAU",
           "default_tau"]

#: The step when no pilot can choose one (methods without a splitting
#: scheme, or when no step meets the tolerance; see :mod:`varint.stepsize`).
DEFAULT_TAU = stepsize.FALLBACK_TAU


def default_tau(model):
    """τ when none is given: :data:`DEFAULT_TAU` for a flow, one iteration
    for a map."""
    return 1.0 if getattr(model, "kind", "flow") == "map" else DEFAULT_TAU


@dataclass(frozen=True)
class RunSpec:
    """One run's inputs, every one checked (built by :func:`specify`).

    Attributes
    ----------
    model : Model
        The model, a copy carrying ``escape_radius`` where the call gave one.
    x0 : ndarray, shape (M, 2N)
    single : bool
        Whether the caller passed one state (results drop the orbit axis).
    reference : varint.accuracy.Reference or None
        The conserved quantities at ``x0`` and their scales (None in the
        specification a map sends to its chunks, whose runs measure their
        own orbits'; :meth:`without_orbits`).
    indicator : Indicator
    options : dict
        The indicator's options, configured for the model
        (:meth:`Indicator.configure`).
    method : str
    method_options : dict
        The method's own options (``scheme``, tolerances, …), checked by the
        propagator when it is built.
    t_end : float
    tau : float or None
        None: chosen by a pilot (:mod:`varint.stepsize`).
    t_out : None, int or ndarray
        The output times as checked (:func:`varint.state.output_steps`).
    steps : ndarray of int or None
        Output steps, once τ is fixed.
    tau_choice : dict
        How τ was chosen (``{"rule": "given"}`` or the pilot's record).
    seed : int or None
        Seed of the random initial deviation vectors (None: drawn by the
        run, or vectors given).
    escape_radius : float or None
        The call's own escape radius (None: the model's).
    energy_tol : float
    """

    model: Any
    x0: np.ndarray
    single: bool
    reference: accuracy.Reference | None
    indicator: Indicator
    options: dict
    method: str
    method_options: dict
    t_end: float
    tau: float | None
    t_out: Any
    seed: int | None
    escape_radius: float | None
    energy_tol: float
    steps: np.ndarray | None = None
    tau_choice: dict = dataclasses.field(default_factory=lambda: {"rule": "given"})

    @property
    def run_options(self):
        """The options of the call that are neither the indicator's nor the
        method's but change the result (recorded in its provenance)."""
        return {} if self.escape_radius is None else {"escape_radius": self.escape_radius}

    @property
    def scheme(self):
        """The ``scheme`` option (None when the method's default is used)."""
        return self.method_options.get("scheme")

    def with_step(self, tau, tau_choice=None, indicator_times=True):
        """This specification with τ fixed (``t_end`` and τ checked against
        each other, :func:`varint._validate.horizon`; the last output is the
        step nearest ``t_end``) and its output steps: those of the
        call's ``t_out``, else the indicator's own default times (unless
        ``indicator_times`` is false: a map's check times), else
        log-spaced ones (:func:`varint.state.output_steps`)."""
        t_end, tau = check.horizon(self.t_end, tau)
        t_out = self.t_out
        if t_out is None and indicator_times and self.indicator.output_times is not None:
            t_out = self.indicator.output_times(t_end, tau, self.options)
        return dataclasses.replace(
            self, t_end=t_end, tau=tau, steps=output_steps(t_end, tau, t_out),
            tau_choice=dict(self.tau_choice if tau_choice is None else tau_choice))

    def with_pilot_step(self, W0=None, k=None, accumulator=None):
        """This specification with τ chosen by a pilot
        (:func:`varint.stepsize.choose_step`, to ``energy_tol`` /
        :data:`~varint.stepsize.PILOT_MARGIN`, no step larger than the first
        output time) carrying the run's initial vectors ``W0`` (or ``k``
        random ones) and ``accumulator``, so that it runs the stepper the
        run will; the pilot's record is kept in ``tau_choice``."""
        t_out = self.t_out
        tau, choice = stepsize.choose_step(
            self.model, self.x0, self.t_end, self.energy_tol / stepsize.PILOT_MARGIN,
            method=self.method, scheme=self.scheme,
            cap=None if t_out is None or np.ndim(t_out) == 0 else float(t_out[0]),
            W0=W0, k=k, renorm=self.indicator.renorm, accumulator=accumulator,
            compensated=self.method_options.get("compensated", False))
        return self.with_step(tau, choice)

    def parameters(self):
        """Everything that determines the runs of this specification (τ and
        its steps fixed) as JSON, without building them: the model, a digest
        of the states, the indicator and its options, the times, the method
        and its options as given, the seed, the call's run options, the
        package versions and the digest of varint's sources. What a
        resumable store keys a piece by (:mod:`varint.store`)."""
        if self.steps is None:
            raise ValueError("the parameters of a specification need its step fixed "
                             "(with_step)")
        return {"kind": self.indicator.name, "model": self.model.describe(),
                "x0": digest(self.x0), "t_end": self.t_end, "tau": self.tau,
                "t_out": digest(self.steps), "method": self.method,
                "method_options": described(self.method_options), "seed": self.seed,
                "options": {**self.options, **self.run_options},
                "versions": package_versions(), "code": identity.source_digest()}

    def with_states(self, x0, what="x0", kernels_what="the initial state", kernel_check=None,
                    reference=True):
        """This specification over the states ``x0`` ((2N,) or (M, 2N)),
        checked (shape, finite, the model's kernels finite there, what the
        indicator requires of them) with the reference their errors are
        measured against (:class:`varint.accuracy.Reference`); ``what``
        and ``kernels_what`` name the states and one state in messages;
        ``kernel_check`` (a :class:`varint._validate.KernelCheck` of this
        model) checks the kernels with buffers kept between calls;
        ``reference=False`` leaves the reference to the caller (None; a
        prepared run's short call measures it with its outputs,
        :func:`varint.accuracy.reference_and_errors`)."""
        x, single, reference = _checked_states(self.model, self.indicator, self.options, x0,
                                               what, kernels_what, kernel_check,
                                               measure=reference)
        # A copy with three fields changed, without dataclasses.replace's
        # __init__ over every field (a prepared run's call makes one).
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__, x0=x, single=single, reference=reference)
        return new

    def checked_states(self, x0, kernel_check=None):
        """(x (M, 2N), single) of the states ``x0``, checked as
        :meth:`with_states` checks them, with the same errors, without a
        reference and without a new specification (a prepared run's short
        call, :mod:`varint.prepared`, which needs only the states)."""
        model = self.model
        if (kernel_check is not None and model.kind != "map"
                and getattr(model, "band_kernels", True)):
            # One state and its kernels tested finite in one pass
            # (KernelCheck.states); where it cannot say, or the indicator
            # refuses the state, the checks below, in _checked_states'
            # order, raise what is wrong.
            checked = kernel_check.states(x0)
            if checked is not None:
                try:
                    self.indicator.check_states(model, checked[0], self.options)
                except ValueError:
                    pass
                else:
                    return checked
        x, single, _ = _checked_states(self.model, self.indicator, self.options, x0, "x0",
                                       "the initial state", kernel_check, measure=False)
        return x, single

    def one_state(self, what="x0"):
        """The state of a specification of one orbit (2N,); a batch is
        refused (for workflows of one orbit: departure, scheme selection)."""
        if not self.single:
            raise ValueError(f"{what} must be one state of shape ({self.model.dim},), got shape "
                             f"{self.x0.shape}")
        return self.x0[0]

    def without_orbits(self):
        """This specification, τ and its steps fixed, without its states and
        their reference: what a chaos map sends to every chunk, whose run
        takes its own orbits (:meth:`for_orbits`)."""
        if self.steps is None:
            raise ValueError("a specification sent to chunks needs its step fixed (with_step)")
        return dataclasses.replace(self, x0=self.x0[:0], single=False, reference=None,
                                   t_out=None)

    def for_orbits(self, x0, reference=None):
        """The specification of a run over ``x0`` (M, 2N), some of the
        orbits this one was checked with (a chaos map's chunk), with their
        ``reference`` (:meth:`varint.accuracy.Reference.rows` of the map's)
        or None: the run computes it."""
        return dataclasses.replace(self, x0=x0, single=False, reference=reference)


def specify(model, x0, indicator: str | Indicator, t_end, tau=None, *, method="tm",
            t_out=None, seed: int | None = 0, escape_radius=None, energy_tol=None,
            what="x0", kernels_what="the initial state", t_out_name="t_out",
            **options) -> RunSpec:
    """The :class:`RunSpec` of a call, every argument checked before any
    work (the arguments of :func:`varint.run`; ``what``, ``kernels_what``
    and ``t_out_name`` name the states, one state and the output times in
    messages): the checks of :func:`specify_call`, then those of
    :meth:`RunSpec.with_states`.

    Raises
    ------
    ValueError
        Naming the value and what was expected: a model that is not one, an
        indicator option the indicator fixes, states of the wrong shape or
        where the potential or its derivatives are not finite, bad output
        times, seed or energy tolerance, an unknown method.
    TypeError
        For an option that neither the indicator nor, when a pilot chooses
        τ, the method takes (the method checks its own when it is built).
    """
    fields = _call_fields(model, indicator, t_end, tau, method=method, t_out=t_out, seed=seed,
                          escape_radius=escape_radius, energy_tol=energy_tol,
                          t_out_name=t_out_name, **options)
    x, single, reference = _checked_states(fields["model"], fields["indicator"],
                                           fields["options"], x0, what, kernels_what,
                                           energies=_device_energies(fields))
    return RunSpec(x0=x, single=single, reference=reference, **fields)


def _device_energies(fields):
    """For ``backend="cuda"`` where a GPU (or the simulator) is present
    and computes the model's energy: the function giving T and V of the
    states there (:func:`varint.gpu.energy.kinetic_and_potential`), else
    None (the host's NumPy; a run without a GPU is refused later, in one
    line, by its propagator)."""
    if fields["method_options"].get("backend") != "cuda" or fields["model"].kind == "map":
        return None
    from .gpu import device, energy

    if not (device.available() and energy.supported(fields["model"])):
        return None
    return functools.partial(energy.kinetic_and_potential, fields["model"])


def specify_call(model, indicator: str | Indicator, t_end, tau=None, *, method="tm",
                 t_out=None, seed: int | None = 0, escape_radius=None, energy_tol=None,
                 t_out_name="t_out", **options) -> RunSpec:
    """The :class:`RunSpec` of a call without its states: every argument
    but ``x0`` checked (those of :func:`specify`), ``x0`` empty (0, 2N).
    :meth:`RunSpec.with_states` adds the states; a prepared run
    (:mod:`varint.prepared`) adds each call's."""
    fields = _call_fields(model, indicator, t_end, tau, method=method, t_out=t_out, seed=seed,
                          escape_radius=escape_radius, energy_tol=energy_tol,
                          t_out_name=t_out_name, **options)
    return RunSpec(x0=np.empty((0, fields["model"].dim)), single=False, reference=None,
                   **fields)


def _call_fields(model, indicator, t_end, tau, *, method, t_out, seed, escape_radius,
                 energy_tol, t_out_name, **options):
    """The fields of a :class:`RunSpec` but its states, checked."""
    model = check.model(model)
    ind, fixed = resolve(indicator)
    given = {k: v for k, v in options.items() if k in ind.options}
    clash = sorted(set(given) & set(fixed))
    if clash:
        raise ValueError(f"indicator {indicator!r} fixes {clash[0]} = {fixed[clash[0]]!r}; "
                         f"do not pass {clash[0]}= with it")
    method_options = {k: v for k, v in options.items()
                      if k not in ind.options and not (k == "scheme" and v is None)}
    if escape_radius is not None:
        # A copy, so the caller's model keeps its own radius.
        escape_radius = check.positive_float(escape_radius, "escape_radius")
        model = copy.copy(model)
        model.escape_radius = escape_radius
    is_map = model.kind == "map"
    energy_tol = accuracy.energy_tolerance(energy_tol)
    if tau is None and is_map:
        tau = default_tau(model)      # one iteration: no step to choose
    # Times are checked against t_end now only for the automatic step, whose
    # pilot comes first (with τ given, output_steps checks them against
    # t_end rounded to whole steps).
    t_out = check.output_times(t_out, t_out_name, t_end if tau is None and isinstance(
        t_end, (int, float)) and np.isfinite(t_end) else None)
    configured = ind.configure(model, {**fixed, **given})
    method = check.choice(method, METHODS, "method")
    if tau is None and stepsize.pilots(method):
        stepsize.check_options(method, method_options)
    if tau is None:
        # Even the largest step a pilot may choose must fit the counter.
        check.step_count(check.end_time(t_end), stepsize.TAU_MAX)
    return {"model": model, "indicator": ind, "options": configured, "method": method,
            "method_options": method_options, "t_end": t_end, "tau": tau, "t_out": t_out,
            "seed": check_seed(seed), "escape_radius": escape_radius, "energy_tol": energy_tol}


def _checked_states(model, indicator, options, x0, what, kernels_what, kernel_check=None,
                    energies=None, measure=True):
    """(x (M, 2N), single, reference) of the states ``x0`` (see
    :meth:`RunSpec.with_states`; ``measure=False``: reference None);
    ``energies``: None, or a function giving T and V of the states
    (:func:`_device_energies`)."""
    x, single = check.states(model, x0, what)
    if model.kind != "map" and getattr(model, "band_kernels", True):
        # A state where V or its derivatives are singular is refused here,
        # not reported as a run failing at its first step (a lattice
        # without band kernels is checked by its own stepper).
        if kernel_check is None:
            check.kernels(model, x, kernels_what)
        else:
            kernel_check(x, kernels_what)
    if measure:
        reference = accuracy.Reference(model, x, None if energies is None else energies(x))
        indicator.check_states(model, x, options)
        return x, single, reference
    try:
        indicator.check_states(model, x, options)
    except ValueError:
        accuracy.Reference(model, x)    # its refusal comes first, as above
        raise
    return x, single, None


def described(options):
    """Method options as JSON: a scheme object by its description."""
    return {k: (v.describe() if callable(getattr(v, "describe", None)) else v)
            for k, v in options.items()}


def check_seed(seed, none=True):
    """``seed`` as an int, or None where ``none`` allows it; anything else
    is refused."""
    if seed is None and none:
        return None
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer{' or None' if none else ''}, "
                         f"got {seed!r}")
    return int(seed)
