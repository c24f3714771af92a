"""Integration methods behind the single ``method=`` switch.

A method is a *propagator*: an object that advances a
:class:`~varint.state.RunState` by whole renormalisation intervals τ. Every
indicator (Lyapunov spectrum, GALI, SALI, …) is written once against this
protocol, so every method feeds the same indicator code.

Rules a propagator must follow
------------------------------
1. ``__init__(model, tau, renorm, **options)``; ``renorm`` is one of
   ``"qr"``, ``"normalize"``, ``"none"``. Unknown options raise
   ``TypeError`` (a misspelt tolerance must not pass silently).
2. ``advance(state, n)`` moves every orbit whose ``state.status`` is 0 by
   ``n`` intervals of length τ, renormalising the deviation vectors after
   each interval with :func:`varint._kernels.renormalize` (or the same
   algorithm) and multiplying the removed stretching into
   ``state.acc_m``/``state.acc_e``. It increments ``state.step`` by ``n``.
3. ``advance(state, a)`` then ``advance(state, b)`` gives bitwise the same
   state as ``advance(state, a + b)``: runs are chunked for progress,
   interruption and checkpoints.
4. A failing orbit gets a non-zero ``state.status`` and ``state.fail_step``
   (the 1-based interval in which it failed) and is not advanced again;
   nothing is raised from inside ``advance``.
5. Work is counted in ``state.counts`` (force, Hessian or right-hand-side
   evaluations), so cost comparisons do not rest on wall time alone.
6. ``describe()`` returns the JSON-serialisable settings that determine the
   result (scheme, tolerances, …) for the result's provenance, and
   ``versions()`` the packages the method ran on.
7. ``k = 0`` deviation vectors must cost no tangent work.
8. Everything that determines how a run continues lives in the RunState
   (method-specific arrays, such as an adaptive step size, in
   ``state.extra``); the propagator object holds only its settings. So a
   saved RunState is a complete checkpoint, and resuming from it is bitwise
   identical to not stopping.
"""

from __future__ import annotations

import importlib

from ._validate import choice

__all__ = ["METHODS", "make_propagator", "RENORM_MODES"]

#: ``method=`` name → "module:class" (imported on first use, so heyoka and
#: SUNDIALS load only when asked for).
METHODS = {
    "tm": "varint.tangent_map:TangentMapPropagator",
    "tdhcc": "varint.tdh.propagators:TDHccPropagator",
    "tdhes": "varint.tdh.propagators:TDHesPropagator",
    "tdheps": "varint.tdh.propagators:TDHepsPropagator",
    "taylor": "baselines.taylor:TaylorPropagator",
    "cvode": "baselines.cvode:CVODEPropagator",
    "dop853": "baselines.dop853:DOP853Propagator",
}

RENORM_MODES = ("qr", "normalize", "none")


def make_propagator(method, model, tau, renorm, **options):
    """Build the propagator registered under ``method``.

    Raises
    ------
    ValueError
        For an unknown method (the message lists the valid ones) or renorm.
    """
    key = choice(method, METHODS, "method")
    renorm = choice(renorm, RENORM_MODES, "renorm")
    module, _, cls = METHODS[key].partition(":")
    return getattr(importlib.import_module(module), cls)(model, tau, renorm, **options)
