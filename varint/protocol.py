"""The run's vocabulary and contracts: what every layer of varint agrees on.

* :class:`Status` — the state of an orbit during a run (fine, stopped on
  purpose, or failed and why), with :data:`REASONS` explaining each failure.
* :class:`Renorm` — how deviation vectors are renormalised at the end of
  every interval τ.
* :class:`Propagator` — what an integration method must do (the numbered
  rules every method follows, so that every indicator works with every
  method, checkpoints resume bitwise and failures are reported alike).
* :class:`Accumulator` — a quantity an indicator accumulates after every
  interval (MEGNO, FLI, …), computed by the same compiled code inside every
  method, with its :class:`UpdateRule` for the generated steppers.

Nothing here imports the rest of varint: every other module may import it.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

__all__ = ["Status", "Renorm", "REASONS", "TANGENT_LIMIT", "COUNTERS", "TIME_MOMENTUM",
           "Propagator", "Accumulator", "UpdateRule", "is_failure", "STATUS_OK"]


class Status(enum.IntEnum):
    """State of one orbit during a run (``RunState.status``).

    Zero while the orbit is advanced; negative when it was stopped on
    purpose; positive when it failed (its later outputs are NaN, see
    :data:`REASONS`).
    """

    #: Frozen by early stopping once its indicator decided its nature (maps).
    DECIDED = -1
    OK = 0
    ORBIT_NONFINITE = 1
    ESCAPED = 2
    TANGENT_DEGENERATE = 3
    TANGENT_OVERFLOW = 4
    #: An adaptive integrator gave up with a finite state.
    INTEGRATOR_FAILED = 5
    #: A model kernel returned a non-finite value at a finite state: the
    #: potential (or its derivatives) is singular on the orbit.
    GRADIENT_NONFINITE = 6
    HESSIAN_NONFINITE = 7
    THIRD_NONFINITE = 8
    #: The potential (or another conserved quantity) is not finite at an
    #: output time although its derivatives were: V is singular or not real
    #: where the orbit is (e.g. log x at x < 0). Found by the run when it
    #: records, not by the stepper.
    POTENTIAL_NONFINITE = 9
    #: Two planets came closer than the close-encounter distance
    #: (:class:`varint.models.Planetary`, in mutual Hill radii).
    CLOSE_ENCOUNTER = 10
    #: A Kepler drift could not be solved (a planet on the star or a
    #: degenerate state: :mod:`varint.kernels.kepler`).
    KEPLER_FAILED = 11


#: ``Status.OK`` as a plain int, for comparisons with status arrays: NumPy
#: compares an array with an IntEnum member about five times slower
#: (~2 µs, several times per run).
STATUS_OK = int(Status.OK)


def is_failure(status):
    """Whether a status code (or array of them) marks a failed orbit."""
    return status > STATUS_OK


#: Why an orbit failed, for error messages.
REASONS = {
    Status.ORBIT_NONFINITE: "the orbit became non-finite (overflow or NaN)",
    Status.ESCAPED: "the orbit escaped: |q| exceeded the model's escape_radius",
    Status.TANGENT_DEGENERATE: "a deviation vector became zero or non-finite",
    Status.TANGENT_OVERFLOW: ("the unrenormalised deviation vectors exceeded 1e+300; "
                              "renormalise them (lyapunov_spectrum, gali) or shorten the run"),
    Status.INTEGRATOR_FAILED: ("the integrator gave up with a finite state (too many steps or "
                               "repeated error-test failures in one interval)"),
    Status.GRADIENT_NONFINITE: ("the gradient of the potential is not finite at the orbit's "
                                "position: the potential is singular (or overflows) there"),
    Status.HESSIAN_NONFINITE: ("the Hessian of the potential is not finite at the orbit's "
                               "position: the potential is singular (or overflows) there"),
    Status.THIRD_NONFINITE: ("the third derivatives of the potential (needed by the "
                             "corrector) are not finite at the orbit's position"),
    Status.POTENTIAL_NONFINITE: ("the potential is not finite at the orbit's position (it is "
                                 "singular or not real there) although its derivatives were, "
                                 "so the energy is undefined; found at this output time"),
    Status.CLOSE_ENCOUNTER: ("two planets came closer than the model's close-encounter "
                             "distance (close_encounter, in mutual Hill radii): the "
                             "Wisdom-Holman map does not resolve an encounter"),
    Status.KEPLER_FAILED: ("a planet's Kepler drift could not be solved (the planet is on the "
                           "star or its state is degenerate)"),
}

#: Unrenormalised deviation vectors larger than this are reported as overflow.
TANGENT_LIMIT = 1e300

#: Work counted per orbit by the compiled steppers: ∇V evaluations, D²V
#: evaluations, third-derivative contractions, kick products on the
#: deviation vectors (D²V·W or D²C·W).
COUNTERS = ("gradient", "hessian", "third", "tangent_products")


#: Key in ``RunState.extra`` of the orbits' momenta p_t conjugate to time
#: (M,), kept by every method for a time-dependent V (integrated in the
#: extended phase space, t = step·τ): K = H(x, t) + p_t is conserved.
TIME_MOMENTUM = "p_t"


class Renorm(enum.IntEnum):
    """How deviation vectors are renormalised at the end of every interval.

    ``QR`` re-orthonormalises them (modified Gram–Schmidt; the diagonal of R
    is the stretching of each vector, paper eq. 10): Lyapunov spectra.
    ``NORMALIZE`` scales each to unit length (paper eq. 15): GALI, SALI,
    MEGNO. ``NONE`` leaves the raw tangent map (plain integration).
    """

    NONE = 0
    NORMALIZE = 1
    QR = 2

    @classmethod
    def parse(cls, value):
        """A :class:`Renorm` from itself or its name ("qr", "normalize",
        "none"), case-insensitively."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str) and value.upper() in cls.__members__:
            return cls[value.upper()]
        raise ValueError(f"unknown renormalisation {value!r}; expected one of: "
                         f"{', '.join(m.name.lower() for m in cls)}")


@dataclass(frozen=True)
class UpdateRule:
    """An accumulator's update written as source, which a generated stepper
    (:mod:`varint.codegen`) writes into its loop — and into its SIMD lanes,
    where calling a compiled update per orbit and step would keep the loop
    over orbits scalar.

    The statements are Python, one assignment each, without branches
    (choose with ``a if c else b``): after each renormalisation they run for
    every vector, reading

    * the live columns, by name (their values so far);
    * ``r``, the vector's stretching over the interval; ``t``, the time;
    * ``am`` and ``ae``, its stretching so far as a mantissa and a binary
      exponent (:mod:`varint.kernels.checks`), including this interval's;
    * ``dot(a, b)`` for ``a``, ``b`` among ``x`` (the state), ``w`` (the
      renormalised vector) and ``f`` (the phase-space velocity, when the
      accumulator ``needs_flow``), summed from 0.0 in the order of the
      components;
    * ``math``, ``np``, ``abs``, ``float``, ``int``, ``max``, ``min``, and
      the constants ``ACC_BIG``, ``ACC_SMALL`` (2^±500) and ``LN2``;

    and assigning live columns and names of their own (temporaries).

    Attributes
    ----------
    live : tuple of str
        The columns carried from one interval to the next.
    step : tuple of str
        The statements run after each renormalisation.
    readout : tuple of str
        Statements that give the other columns (from the live ones, ``am``
        and ``ae``) when the state is copied out; none when every column is
        live.
    """

    live: tuple
    step: tuple
    readout: tuple = ()


@dataclass(frozen=True)
class Accumulator:
    """Quantities accumulated per deviation vector after every interval.

    Indicators such as MEGNO need the stretching of every interval, not only
    the state at output times. Every propagator calls ``update`` after it
    renormalised the vectors at the end of an interval ending at time t, so
    the same compiled code serves every method (rule 9 of
    :class:`Propagator`).

    Attributes
    ----------
    name : str
        Key of the accumulator array in ``RunState.extra``.
    columns : tuple of str
        Names of the accumulated values of each vector.
    initial : tuple of float
        Their values at t = 0.
    update : numba dispatcher
        ``update(aux, r, x, W, flow, t)``: ``aux`` (k, len(columns)) is
        updated in place; ``r`` (k,) holds the stretching factor of each
        vector over the interval (the norm removed, or R_jj of the QR
        decomposition), ``x`` (2N,) the state and ``W`` (2N, k) the
        renormalised vectors at time ``t``, ``flow`` (2N,) the phase-space
        velocity ẋ at ``x`` (empty unless ``needs_flow``).
    needs_flow : bool
        Whether ``update`` reads ``flow``. Maps have none: they pass an
        empty ``flow`` (and the OFLI indicator refuses map models).
    rule : UpdateRule, optional
        The update as source, for the generated steppers, which then write
        it into their loops instead of calling ``update``. The same
        arithmetic as ``update`` gives the same bits
        (:func:`varint.codegen.accumulators.compile_update` compiles
        ``update`` from the rule); a rule of its own (FLI's) agrees with
        ``update`` to round-off.
    """

    name: str
    columns: tuple
    initial: tuple
    update: Any
    needs_flow: bool = False
    rule: UpdateRule | None = None

    def __post_init__(self):
        if len(self.columns) != len(self.initial) or not self.columns:
            raise ValueError(f"accumulator {self.name!r}: columns and initial values must "
                             "be equally long and not empty")
        if self.rule is not None and not set(self.rule.live) <= set(self.columns):
            raise ValueError(f"accumulator {self.name!r}: the live columns of its rule "
                             f"{tuple(self.rule.live)} are not all among its columns "
                             f"{tuple(self.columns)}")

    @property
    def key(self):
        """Where its array (M, k, len(columns)) lives in ``RunState.extra``."""
        return f"acc_{self.name}"


@runtime_checkable
class Propagator(Protocol):
    """An integration method: advances a :class:`~varint.state.RunState` by
    whole intervals τ. Every indicator is written once against this
    protocol, so every method feeds the same indicator code.

    Rules a propagator must follow
    ------------------------------
    1. ``__init__(model, tau, renorm, accumulator=None, **options)``;
       ``renorm`` is a :class:`Renorm`. Unknown options raise ``TypeError``
       naming the valid ones (a misspelt tolerance must not pass silently).
    2. ``advance(state, n)`` moves every orbit whose ``state.status`` is OK
       by ``n`` intervals of length τ, renormalising the deviation vectors
       after each interval with :func:`varint.kernels.checks.renormalize`
       (or the same algorithm) and multiplying the removed stretching into
       ``state.acc_m``/``state.acc_e``. It increments ``state.step`` by
       ``n``.
    3. ``advance(state, a)`` then ``advance(state, b)`` gives bitwise the same
       state as ``advance(state, a + b)``: runs are chunked for progress,
       interruption and checkpoints.
    4. A failing orbit gets a failure :class:`Status` and ``state.fail_step``
       (the 1-based interval in which it failed) and is not advanced again;
       nothing is raised from inside ``advance``. The orbit is checked at
       the end of every interval with :mod:`varint.kernels.checks`.
    5. Work is counted in ``state.counts`` (force, Hessian or right-hand-side
       evaluations), so cost comparisons do not rest on wall time alone.
    6. ``describe()`` returns the JSON-serialisable settings that determine
       the result (scheme, tolerances, …) for the provenance, and
       ``versions()`` the packages the method ran on.
    7. ``k = 0`` deviation vectors cost no tangent work.
    8. Everything that determines how a run continues lives in the RunState
       (method-specific arrays in ``state.extra``); the propagator object
       holds only its settings. A saved RunState is a complete checkpoint,
       and resuming from it is bitwise identical to not stopping.
    9. With an ``accumulator``, its ``update`` is called after the
       renormalisation at the end of every interval, on the array
       ``state.extra[accumulator.key]`` (created by the run).
    """

    method: str
    tau: float

    def advance(self, state, n): ...

    def describe(self) -> dict: ...

    def versions(self) -> dict: ...
