"""A run prepared once and run from many initial conditions:
:func:`prepare` → :class:`PreparedRun`, called with each ``x0``.

A researcher's short runs are mostly the same model, indicator, method,
scheme, τ and times from different initial states (a scan, a bisection, a
Monte Carlo sample), and a one-shot call (:func:`varint.run`) checks and
builds all of that again every time. A prepared run checks the arguments
once (:func:`varint.runspec.specify_call`, output steps fixed), builds its
propagator at the first call and keeps it; each call then only checks its
states (shape, finite, the model's kernels finite there, what the
indicator requires), measures their reference energy, starts the state and
drives it (:meth:`varint.run.Run.with_orbits`). A short call (one expected
to last less than one of the driver's chunks, 0.2 s, by a generated TM
stepper on the CPU) takes a shorter path, :class:`varint.rerun.ShortCall`:
the whole run in one stepper call on buffers kept per thread, the outputs
read once, the energy errors and the verdict in one compiled pass, the
result assembled directly, everything that does not depend on the states
made once (issue 28: the fixed cost of a call). The result is the one-shot
call's, bitwise, with the same type and provenance (heyoka's counterpart
is a built integrator's ``propagate_until`` from a new state). A one-shot
call that repeats an earlier call's arguments takes the same path
(:mod:`varint.remembered`).
"""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike

from . import _validate as check
from .indicators import Indicator
from .models.base import Model
from .rerun import Rerun
from .results import _Result
from .run import Run
from .runspec import RunSpec, specify_call

__all__ = ["prepare", "PreparedRun"]


def prepare(model: Model, indicator: str | Indicator, t_end: float, tau: float | None = None,
            *, deviations: ArrayLike | None = None, progress: bool | None = None,
            errors: str = "raise", **options: Any) -> PreparedRun:
    """A run of ``indicator`` along ``model`` to ``t_end`` with step ``tau``,
    checked once, to be called with each initial state.

    Parameters
    ----------
    model, indicator, t_end
        As for :func:`varint.run`.
    tau : float
        The step (renormalisation interval); required for a flow (the
        automatic step is chosen per orbit by a pilot run: give the τ a
        one-shot run chose, ``result.provenance.tau``); for a map, one
        iteration by default.
    deviations : array_like, shape ([M,] 2N, k), optional
        Initial deviation vectors of every call that passes none (else
        seeded random ones, ``seed``); they fix how many vectors each call
        carries.
    progress : bool, optional
        As for :func:`varint.run`: a progress bar on stderr (after a second)
        and the announcement of a long first compilation, by default only
        on a terminal.
    errors : {"raise", "flag"}
        As for :func:`varint.run`.
    **options
        As for :func:`varint.run` (``method``, ``scheme``, ``t_out``,
        ``seed``, ``escape_radius``, ``energy_tol``, the indicator's and the
        method's options); not ``checkpoint`` (a file belongs to one run).

    Returns
    -------
    PreparedRun
        Call it with ``x0`` ((2N,) or (M, 2N)) and optionally
        ``deviations``: the result of ``varint.run(model, x0, indicator,
        t_end, tau, ...)``, bitwise.

    Raises
    ------
    ValueError
        For bad arguments, before any work (as :func:`varint.run`), and for
        ``tau=None`` on a flow.

    Examples
    --------
    >>> import varint
    >>> model, x0 = varint.paper_orbit("R1")
    >>> run = varint.prepare(model, "megno", t_end=100.0, tau=0.05)
    >>> ys = [run(x0 + [0.0, 0.0, dp, 0.0]).mean_megno[-1] for dp in (0.0, 1e-3, 2e-3)]
    >>> bool(ys[0] == varint.megno(model, x0, 100.0, tau=0.05).mean_megno[-1])
    True
    """
    if "checkpoint" in options or "checkpoint_interval" in options:
        raise ValueError("a prepared run takes no checkpoint (a checkpoint file belongs to one "
                         "run); use varint.run(..., checkpoint=path) for a long run")
    spec = specify_call(model, indicator, t_end, tau, **options)
    if spec.tau is None:
        raise ValueError("a prepared run needs tau= (the automatic step is chosen per orbit by "
                         "a pilot run); give the step a one-shot run chose "
                         "(result.provenance.tau)")
    return PreparedRun(spec.with_step(spec.tau), deviations, check.flag(progress, "progress"),
                       check.choice(errors, ("raise", "flag"), "errors"))


class PreparedRun:
    """A run checked once, called with each initial state (built by
    :func:`prepare`).

    Attributes
    ----------
    spec : varint.runspec.RunSpec
        What every call runs, τ and the output steps fixed, without states.
    """

    def __init__(self, spec: RunSpec, deviations: ArrayLike | None, progress: bool | None,
                 errors: str) -> None:
        self.spec = spec
        self._deviations = deviations
        self._progress, self._errors = progress, errors
        # The first call's run and its calls again (Rerun: its propagator,
        # set-up and short path serve every later call).
        self._first: Run | None = None
        self._again: Rerun | None = None

    def __call__(self, x0: ArrayLike, deviations: ArrayLike | None = None) -> _Result:
        """The result of the run from ``x0`` ((2N,) or (M, 2N)), with
        ``deviations`` (([M,] 2N, k), as many vectors as the prepared run
        carries) or the prepared run's vectors."""
        again = self._again
        if again is not None:
            return again(x0, deviations, self._deviations)
        # The kernels' check at each call's states, its buffers kept.
        kernel_check = check.KernelCheck(self.spec.model)
        spec = self.spec.with_states(x0, kernel_check=kernel_check)
        vectors = self._deviations if deviations is None else deviations
        self._first = first = Run(spec, deviations=vectors, progress=self._progress,
                                  errors=self._errors)
        result = first.execute()
        self._again = Rerun(first, result.provenance.timing.get("run", float("inf")),
                            kernel_check)
        return result

    def __repr__(self):
        s = self.spec
        return (f"PreparedRun({s.indicator.name} of {s.model.name} by {s.method}, "
                f"tau={s.tau:g}, t_end={s.t_end:g})")
