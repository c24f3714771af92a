"""Chaos maps: one indicator for many initial conditions, on this machine or
on a Dask cluster.

A map evaluates an indicator — any of :data:`varint.INDICATORS` that has a
map value (SALI, GALI_k, X1, MEGNO, FLI, OFLI, local exponents, or one a
user registered) — for an (M, 2N) array of initial conditions or a grid on
a surface of section (:func:`varint.section_grid`). It uses the same
:class:`~varint.indicators.Indicator` objects and the same run
(:func:`varint.run.prepare`) as single runs. The orbits are split
into chunks; a chunk is one batch run of the compiled integrator, parallel
over its orbits (numba ``prange``), so nothing per orbit passes through
Python. With a ``dask.distributed.Client`` the chunks run on the cluster, one
task each, and come back as they finish.

Deterministic by construction: orbit m's deviation vectors are drawn from
``default_rng([seed, m])`` with m its index in the whole map
(:func:`varint.state.initial_deviations`), every stepper advances each orbit
on its own, and early stopping is decided at fixed check times, never at the
wall-clock chunk boundaries of the run loop. So a value does not depend on
the chunk size, the worker, the number of threads or on resuming.

Early stopping: once an orbit's indicator has settled (SALI or GALI_k below
the threshold: chaotic) the orbit is frozen (status ``DECIDED``) and costs
nothing more; its value is the one at the check time that decided it, and
``t_stop`` says when.

Resuming: with ``checkpoint=DIR`` each finished chunk is written to ``DIR``
(atomically, :class:`varint.store.Store`) as soon as it arrives; the same
call again loads the finished chunks and computes only the others, so a map
interrupted at 90 % resumes at 90 %. A directory written by a map with other
parameters (``map.json``) is refused with a :class:`~varint.CheckpointError`
naming them. Each chunk file carries the key of its map and its orbits, and
is checked before use (:func:`_checked_chunk`): an unreadable, edited or
foreign chunk (copied from another map, or left by one after ``map.json``
was lost) is reported and recomputed (a chunk is a deterministic,
cheap-to-redo piece of the map, unlike a run checkpoint that may stand for
days). A full or unwritable directory costs one warning: the map goes on.
"""

from __future__ import annotations

import contextlib
import copy
import math
import numbers
import os
import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from . import _validate as check
from . import accuracy, compiling, identity, stepsize, stepsize_orbits
from .checkpoint import digest
from .indicators import INDICATORS, Indicator, resolve
from .methods import METHODS, propagator_class
from .models.base import Model
from .protocol import REASONS, STATUS_OK, Status, is_failure
from .results import ChaosMapResult, Provenance, package_versions
from .run import default_tau, prepare
from .grids import SectionGrid
from .state import initial_deviations, output_steps
from .store import Invalid, Store

__all__ = ["chaos_map", "MAP_SCHEME", "MAP_PILOT_TOL", "pilot_tolerance"]

#: The scheme of a map whose step is chosen automatically, and the energy
#: error its pilot must meet: for each of the SALI, MEGNO and FLI maps of the
#: Hénon–Heiles section, the cheapest pair (in force evaluations) that
#: classifies orbits as a tight reference does at least as often as both
#: SBAB2C at the paper's τ = 0.05 and heyoka's batch mode at tol 1e-6
#: (studies/map_defaults.py). SRKN14a (order 6) at 1e-7 takes τ ≈ 0.71
#: there, half SBAB2C's force evaluations at τ = 0.05: MEGNO 100 %, FLI
#: 98.7 % (SBAB2C 100 %, 98.4 %; heyoka 100 %, 98.4 %). SALI needs 1e-8
#: (τ = 0.5, 98.2 % against SBAB2C's 97.5 % and heyoka's 98.0 %): its
#: indicator declares that tolerance (:func:`pilot_tolerance`).
MAP_SCHEME = "SRKN14a"
MAP_PILOT_TOL = 1e-7


def pilot_tolerance(indicator):
    """The energy error a map's pilot must meet for ``indicator`` (an
    :class:`~varint.indicators.Indicator`): its own ``map_tolerance`` when it
    declares one (SALI's classification needs a tighter step than FLI's and
    MEGNO's, ``studies/map_defaults.py``), else :data:`MAP_PILOT_TOL`."""
    own = indicator.map_tolerance
    return MAP_PILOT_TOL if own is None else own


#: Default check times start at this many steps: each check stops a chunk
#: and reads its records (~0.4 ms for 250 Hénon–Heiles orbits, as much as
#: ~70 of their steps), so the 16 log-spaced checks of the first 63 steps
#: would cost more than an orbit decided there could save.
FIRST_CHECK_STEP = 64
#: The quantile of the pilot orbits' errors that must meet it: a few orbits
#: of a map that escape or graze a singularity do not set the step of all.
MAP_QUANTILE = 0.9


@dataclass
class _Spec:
    """What every chunk of one map shares (sent to the workers)."""

    indicator: object
    indicator_options: dict
    k: int
    t_end: float
    tau: float
    method: str
    method_options: dict
    steps: np.ndarray
    seed: int
    threshold: float | None
    escape_radius: float | None
    #: Per orbit of the map, the divisor n of its step τ = tau / n
    #: (``tau="orbit"``, :mod:`varint.stepsize_orbits`); None: one step.
    divisions: np.ndarray | None = None


@dataclass
class _Chunk:
    """The per-orbit outcome of one chunk, in the chunk's orbit order."""

    values: np.ndarray
    t_stop: np.ndarray
    status: np.ndarray
    energy_error: np.ndarray
    state: np.ndarray
    max_energy_error: np.ndarray | None = None
    max_error: np.ndarray | None = None
    counts: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    interrupted: bool = False
    #: CPU seconds the chunk took (None on a Dask worker, whose process
    #: runs other tasks at the same time).
    cpu_time: float | None = None


@contextlib.contextmanager
def _worker_threads():
    """On a Dask worker, run numba on as many threads as the worker has
    (numba's setting is per calling thread), so workers sharing a machine
    do not oversubscribe it; yields the task's :func:`_cancel_check` there,
    None elsewhere."""
    try:
        from distributed import get_worker

        worker = get_worker()
        n = worker.state.nthreads
    except (ImportError, ValueError, AttributeError):
        yield None
        return
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    try:
        yield _cancel_check(worker)
    finally:
        numba.set_num_threads(before)


def _cancel_check(worker):
    """A function telling whether the Dask task running in this thread was
    cancelled (the map was interrupted): its run then stops at its next
    chunk (~0.2 s) instead of finishing, so an interrupted map leaves no
    worker busy for minutes and a cluster closes at once."""
    try:
        key = worker.get_current_task()
    except Exception:  # not inside a task
        return lambda: False

    def cancelled():
        task = worker.state.tasks.get(key)
        return task is None or task.state in ("cancelled", "released", "forgotten")

    return cancelled


def run_chunk(model, x0, indices, spec):
    """One chunk of a map: the orbits ``x0`` (their ``indices`` in the whole
    map) as one batch run, stopping early at the check times ``spec.steps``.
    """
    if spec.divisions is not None:
        return stepsize_orbits.run_grouped(run_chunk, model, x0, indices, spec)
    ind = spec.indicator
    cpu = time.process_time()
    with _worker_threads() as cancelled, warnings.catch_warnings():
        # Failed orbits are counted by the map, which warns once.
        warnings.simplefilter("ignore", RuntimeWarning)
        W0 = initial_deviations(model.dim, spec.k, len(x0), spec.seed, indices)
        job = prepare(model, x0, ind, spec.t_end, spec.tau, method=spec.method, deviations=W0,
                      t_out=spec.steps * spec.tau, progress=False, errors="flag",
                      escape_radius=spec.escape_radius, **spec.indicator_options,
                      **spec.method_options)

        def record(rows):
            rec = job.record(rows)
            errors = [v for k, v in rec.items()
                      if k == "energy_error" or k.startswith("conserved_error:")]
            return {"value": ind.scalar(rec, model, job.options),
                    "energy_error": rec["energy_error"], "max_error": np.max(errors, axis=0)}

        def decide(rec):
            return ind.settled(rec["value"], spec.threshold)

        records, stop, _ = job.drive(record, None if spec.threshold is None else decide,
                                     cancelled)
    state = job.state
    n_done = 0 if records is None or not records else len(records["value"])
    # Read each orbit at the last output it was active at: where it was
    # decided, else the last one reached.
    at = np.full(len(x0), n_done - 1)
    stopped = state.status == Status.DECIDED
    at[stopped] = np.searchsorted(job.steps[:n_done], state.fail_step[stopped])
    rows = np.arange(len(x0))
    values = records["value"][at, rows] if n_done else np.full(len(x0), np.nan)
    energy = records["energy_error"][at, rows] if n_done else np.full(len(x0), np.nan)
    # The largest errors up to the output each orbit is read at.
    largest = []
    for key in ("energy_error", "max_error"):
        if not n_done:
            largest.append(np.full(len(x0), np.nan))
            continue
        upto = np.where(np.arange(n_done)[:, None] <= at[None, :], records[key], np.nan)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # failed before the first
            largest.append(np.nanmax(upto, axis=0))
    t_stop = np.where(state.status != STATUS_OK, state.fail_step, state.step) * spec.tau
    return _Chunk(values=values, t_stop=t_stop, status=state.status.copy(), energy_error=energy,
                  state=state.x.copy(), max_energy_error=largest[0], max_error=largest[1],
                  counts=dict(state.counts),
                  provenance={"method_options": job.propagator.describe(),
                              "versions": job.versions(), "code": job.code,
                              "machine": job.machine},
                  interrupted=stop == "interrupted",
                  cpu_time=None if cancelled is not None else time.process_time() - cpu)


#: A map chunk's per-orbit arrays and their dtype kinds.
_CHUNK_ARRAYS = {"values": "f", "t_stop": "f", "status": "i", "energy_error": "f", "state": "f",
                 "max_energy_error": "f", "max_error": "f"}


def _chunk_name(c):
    return f"chunk_{c:06d}"


def _save_chunk(store, c, idx, chunk):
    """Keep chunk ``c`` (orbits ``idx``) in the store."""
    arrays = {name: getattr(chunk, name) for name in _CHUNK_ARRAYS}
    store.save(_chunk_name(c), {**arrays, "orbits": np.asarray(idx, dtype=np.int64)},
               {"counts": chunk.counts, "provenance": chunk.provenance,
                "cpu_time": chunk.cpu_time})


def _load_chunk(store, c, idx, spec, dim):
    """Chunk ``c`` of this map from the store if it is there and valid
    (:func:`_checked_chunk`), else None (a damaged or foreign file is
    reported and recomputed)."""
    piece = store.load(_chunk_name(c))
    if piece is None:
        return None
    try:
        return _checked_chunk(piece, idx, spec, dim)
    except Invalid as exc:
        store.discard(store.file(_chunk_name(c)), exc)
        return None


def _checked_chunk(piece, idx, spec, dim):
    """The :class:`_Chunk` a stored piece stands for, after checking that
    it is one this map would have computed for the orbits ``idx``: the
    same orbits, one value per orbit of the right dtype, known status
    codes, stop times on the map's grid, finite values, errors and states
    for every orbit that did not fail, and non-negative counts.

    Raises
    ------
    Invalid
        Naming the field and why.
    """
    a, meta = piece.arrays, piece.meta
    if set(a) != set(_CHUNK_ARRAYS) | {"orbits"}:
        odd = sorted(set(a) ^ (set(_CHUNK_ARRAYS) | {"orbits"}))[0]
        raise Invalid(f"array {odd} is {'missing' if odd not in a else 'not a chunk array'}")
    if a["orbits"].shape != idx.shape or not np.array_equal(a["orbits"], idx):
        raise Invalid("it holds other orbits than this chunk's")
    m = len(idx)
    for name, kind in _CHUNK_ARRAYS.items():
        shape = (m, dim) if name == "state" else (m,)
        if a[name].shape != shape or a[name].dtype.kind != kind:
            raise Invalid(f"{name} is {a[name].dtype}{list(a[name].shape)}, expected "
                          f"{'float64' if kind == 'f' else 'int64'}{list(shape)}")
    status = a["status"]
    known = {int(s) for s in Status}
    if not set(np.unique(status).tolist()) <= known:
        raise Invalid(f"status holds an unknown code {sorted(set(status.tolist()) - known)[0]}")
    fine = ~is_failure(status)
    checks = [(name, np.isfinite(a[name]) if name != "state" else np.isfinite(a[name]).all(1))
              for name in ("values", "energy_error", "max_energy_error", "max_error", "state")]
    for name, finite in checks:
        bad = fine & ~finite
        if bad.any():
            raise Invalid(f"{name} is not finite for orbit {int(idx[np.argmax(bad)])}, which "
                          "did not fail")
    t_end, checks_at = spec.t_end, spec.steps * spec.tau
    t = a["t_stop"]
    ok = np.where(status == STATUS_OK, t == spec.steps[-1] * spec.tau,
                  np.where(status == int(Status.DECIDED), np.isin(t, checks_at),
                           (t > 0) & (t <= t_end * (1 + 1e-12))))
    if not ok.all():
        raise Invalid(f"t_stop of orbit {int(idx[np.argmin(ok)])} is {t[np.argmin(ok)]!r}, not "
                      "a time its status allows")
    with np.errstate(invalid="ignore"):
        negative = fine & ((a["energy_error"] < 0) | (a["max_energy_error"] < 0)
                           | (a["max_error"] < 0))
    if negative.any():
        raise Invalid("an energy error is negative")
    counts, prov, cpu = meta.get("counts"), meta.get("provenance"), meta.get("cpu_time")
    if not isinstance(counts, dict) or not all(
            isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in counts.values()):
        raise Invalid("counts are not non-negative integers")
    if not (isinstance(prov, dict) and isinstance(prov.get("method_options"), dict)
            and isinstance(prov.get("versions"), dict)):
        raise Invalid("provenance is not the chunk's method options and versions")
    if cpu is not None and (isinstance(cpu, bool) or not isinstance(cpu, (int, float))
                            or not 0 <= cpu < math.inf):
        raise Invalid(f"cpu_time is {cpu!r}")
    return _Chunk(**{name: a[name] for name in _CHUNK_ARRAYS}, counts=counts, provenance=prov,
                  cpu_time=cpu)


def _default_chunk_size(m, workers):
    # At least 20 chunks (an interrupted map loses at most 5 % of its work)
    # and two per worker thread, but no chunk under 256 orbits, where the
    # fixed cost of a run would show.
    return int(min(m, max(256, math.ceil(m / max(20, 2 * workers)))))


def _cluster_threads(client):
    info = client.scheduler_info()
    return max(1, sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))


def chaos_map(model: Model, initial_conditions: ArrayLike | SectionGrid,
              indicator: str | Indicator = "sali", *, t_end: float, tau: float | str | None = None,
              method: str = "tm", threshold: float | str | None = "default", seed: int = 0,
              t_check: int | ArrayLike | None = None, chunk_size: int | None = None,
              client: Any = None, checkpoint: str | os.PathLike[str] | None = None,
              progress: bool | None = None, escape_radius: float | None = None,
              energy_tol: float | None = None, **options: Any) -> ChaosMapResult:
    """An indicator for many initial conditions (final SALI, GALI_k, X1,
    MEGNO, FLI, OFLI, local exponents, or any registered indicator with a
    map value), with early stopping once an orbit is decided.

    Parameters
    ----------
    model : Model
    initial_conditions : array_like, shape (M, 2N), or SectionGrid
        The orbits, or a grid on a surface of section
        (:func:`varint.section_grid`, e.g. Hénon–Heiles x = 0, p_x ≥ 0).
    indicator : str or Indicator, default "sali"
        A name of :data:`varint.INDICATORS` with a map value: "sali",
        "gali" (the map shows GALI_k with the largest k ≤ N of its orders),
        "gali_k", "x1", "megno" (the running mean Ȳ), "fli", "ofli",
        "local_exponents", or any indicator registered with
        :func:`varint.register_indicator`.
    t_end : float
        Final time of every orbit not stopped early.
    tau : float, optional
        Step (renormalisation interval). By default the method's pilot
        chooses it (:func:`varint.stepsize.choose_step` on a sample of the
        orbits) for :data:`MAP_SCHEME` unless a ``scheme`` is given, to an
        energy error of :func:`pilot_tolerance` (:data:`MAP_PILOT_TOL`, or the
        indicator's own ``map_tolerance``), and the result records the
        choice (``provenance.tau_choice``); one iteration for a map model.
        ``"orbit"``: each orbit its own step, from its own pilot to the same
        tolerance (:mod:`varint.stepsize_orbits`); the steps divide one unit
        (``provenance.tau``), so the check times stay common, and
        ``provenance.tau_choice["divisions"]`` gives each orbit's divisor n
        of it (τ = tau / n).
    method : str, default "tm"
        As in :func:`varint.run`; every method computes every indicator.
    **options
        The indicator's options (e.g. ``k`` for GALI, ``window`` for local
        exponents) and the method's (e.g. ``scheme``), as for
        :func:`varint.run`.
    threshold : float, None or "default"
        Early stopping: an orbit whose value falls below it (SALI, GALI) or
        rises above it (MEGNO, FLI, OFLI) at a check time is frozen.
        "default": the indicator's (1e-8 for SALI and GALI_k with k ≤ N;
        none for X1, MEGNO, FLI, OFLI and GALI_k with k > N, whose regular
        values fall as power laws); None: no early stopping.
    seed : int, default 0
        Orbit m's random initial deviation vectors come from
        ``default_rng([seed, m])``.
    t_check : None, int or array_like
        Times at which early stopping is decided (see ``t_out`` of
        :func:`varint.lyapunov_spectrum`); by default log-spaced, 10 per
        decade, from :data:`FIRST_CHECK_STEP` steps on. The same for every
        chunk, which keeps the map deterministic.
    chunk_size : int, optional
        Orbits per chunk; by default M/20 (at least 256), and at least two
        chunks per worker thread of a cluster.
    client : dask.distributed.Client, optional
        Run the chunks on this cluster. Values are bitwise the same as
        without it.
    checkpoint : str or os.PathLike, optional
        Directory that keeps the finished chunks; calling again with the
        same arguments resumes (see the module docstring).
    progress : bool, optional
        A progress bar over orbits on stderr (by default when stderr is a
        terminal).
    escape_radius : float, optional
        Stop orbits whose |q| exceeds this (they count as failed).

    Returns
    -------
    ChaosMapResult
        ``values`` (M,), ``t_stop``, ``status`` (0: ran to t_end, −1:
        decided early, > 0: failed, value NaN), ``x0``; for a grid also
        ``image()``. After Ctrl-C: the chunks finished so far (the others
        NaN) with ``interrupted=True``.

    Examples
    --------
    >>> import numpy as np, varint
    >>> model = varint.models.HenonHeiles()
    >>> grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.7, 100),
    ...                            np.linspace(-0.45, 0.45, 100))
    >>> r = varint.chaos_map(model, grid, "sali", t_end=1e3)      # doctest: +SKIP
    >>> plt.imshow(np.log10(r.image()), origin="lower")           # doctest: +SKIP

    A map's phase space (:func:`varint.phase_grid`), t_end in iterations:

    >>> sm = varint.models.StandardMap(1.2)
    >>> grid = varint.phase_grid(sm, np.linspace(0, 2 * np.pi, 64), np.linspace(-np.pi, np.pi, 64))
    >>> r = varint.chaos_map(sm, grid, "x1", t_end=1000)         # doctest: +SKIP

    On a cluster (each worker needs varint installed)::

        from dask.distributed import Client
        client = Client("tcp://scheduler:8786")
        r = varint.chaos_map(model, grid, "sali", t_end=1e4, client=client,
                             checkpoint="hh_sali_map")
    """
    start = time.perf_counter()
    model = check.model(model)
    client = check.dask_client(client)
    grid = initial_conditions if isinstance(initial_conditions, SectionGrid) else None
    if grid is not None:
        if grid.states.size == 0:
            raise ValueError("the section grid holds no allowed point at this energy")
        X, _ = check.states(model, grid.states, "the section grid's states")
    else:
        X, single = check.states(model, initial_conditions, "initial_conditions")
        if single:
            raise ValueError("initial_conditions must have shape (M, 2N) (one row per orbit), "
                             f"got shape {np.asarray(initial_conditions).shape}")
    m = len(X)
    # The map's per-orbit results (values, times, status, errors, states).
    model_name = model.name
    check.check_memory(check.array_bytes((m, 2 * X.shape[1] + 8)),
                       f"a chaos map of {m} orbits of {model_name}")
    if getattr(model, "kind", "flow") == "map":
        tau = default_tau(model) if tau is None else tau   # iterations: no step to choose
    elif getattr(model, "band_kernels", True):
        # An initial condition where V or its derivatives are singular is
        # refused, not computed as a failed orbit.
        check.kernels(model, X, "initial condition")
    accuracy.Reference(model, X)
    energy_tol = accuracy.energy_tolerance(energy_tol)
    ind, fixed = resolve(indicator)
    if ind.scalar is None:
        raise ValueError(f"indicator {ind.name!r} has no map value (one number per orbit); "
                         "maps take: " + ", ".join(n for n, i in INDICATORS.items()
                                                  if i.scalar is not None))
    ind_options = {**fixed, **{k: v for k, v in options.items() if k in ind.options}}
    method_options = {k: v for k, v in options.items()
                      if k not in ind.options and not (k == "scheme" and v is None)}
    # Checked here, before any chunk runs, with the chunks' own rules.
    configured = ind.configure(model, ind_options)
    ind.check_states(model, X, configured)
    k = ind.vectors(model, configured, None)
    limit: float | None
    if isinstance(threshold, str) and threshold == "default":
        limit = ind.default_threshold(model, configured)
    elif threshold is None:
        limit = None
    elif (isinstance(threshold, bool) or not isinstance(threshold, numbers.Real)
            or not np.isfinite(threshold)):
        raise ValueError(f"threshold must be a finite number, None or 'default', "
                         f"got {threshold!r}")
    else:
        limit = float(threshold)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    workers = 1 if client is None else _cluster_threads(client)
    if chunk_size is None:
        chunk_size = _default_chunk_size(m, workers)
    elif isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) \
            or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    if escape_radius is not None:
        escape_radius = check.positive_float(escape_radius, "escape_radius")
    method = check.choice(method, METHODS, "method")
    per_orbit = _per_orbit(tau, model, method, t_check)
    if (tau is None or per_orbit) and stepsize.pilots(method):
        stepsize.check_options(method, method_options)
    progress = check.flag(progress, "progress")
    t_check = check.output_times(t_check, "t_check", t_end if (tau is None or per_orbit) and (
        isinstance(t_end, (int, float)) and np.isfinite(t_end)) else None)
    tau_choice = {"rule": "given"}
    clock = compiling.Clock(f"the {ind.name} map of {model_name} by {method}", progress)
    divisions = None
    if per_orbit:
        check.step_count(check.end_time(t_end), stepsize.TAU_MAX)
        with clock.part("pilot"):
            tau, divisions, tau_choice = _choose_step(
                model, X, t_end, method, method_options, t_check, escape_radius, ind,
                configured, k, seed, per_orbit=True)
    elif tau is None:
        check.step_count(check.end_time(t_end), stepsize.TAU_MAX)
        with clock.part("pilot"):
            tau, tau_choice = _choose_step(model, X, t_end, method, method_options,
                                           t_check, escape_radius, ind, configured, k, seed)
    t_end, tau = check.horizon(t_end, tau)
    steps = output_steps(t_end, tau, t_check)
    if t_check is None:
        steps = steps[(steps >= FIRST_CHECK_STEP) | (steps == steps[-1])]
    spec = _Spec(indicator=ind, indicator_options=ind_options, k=k, t_end=t_end, tau=float(tau),
                 method=method, method_options=method_options, steps=steps, seed=int(seed),
                 threshold=limit, escape_radius=escape_radius, divisions=divisions)
    # A fixed shuffle spreads islands and chaotic seas evenly over chunks
    # and over the threads within a chunk, whose orbits stop at different
    # times; values do not depend on it (see the module docstring).
    order = np.random.default_rng(20100927).permutation(m)
    chunks = [order[i:i + chunk_size] for i in range(0, m, chunk_size)]
    parameters = {"kind": "chaos_map", "model": model.describe(), "x0": digest(X),
                  "indicator": ind.name, "indicator_options": configured,
                  "threshold": limit, "t_end": t_end, "tau": tau,
                  "t_check": digest(steps), "method": spec.method,
                  "method_options": _describe_options(method_options), "seed": int(seed),
                  "chunk_size": int(chunk_size), "escape_radius": escape_radius,
                  "versions": package_versions(), "code": identity.source_digest()}
    if divisions is not None:
        parameters["tau_divisions"] = digest(divisions)
    store = None
    done = {}
    if checkpoint is not None:
        store = Store(checkpoint, "chaos map", parameters)
        store.manifest("map.json")
        for c in range(len(chunks)):
            chunk = _load_chunk(store, c, chunks[c], spec, X.shape[1])
            if chunk is not None:
                done[c] = chunk
    resumed = len(done)
    todo = [c for c in range(len(chunks)) if c not in done]
    runner = _run_local if client is None else _run_dask
    with _bar(progress, m, sum(len(chunks[c]) for c in done)) as bar, clock.part("run"):
        interrupted = runner(client, model, X, chunks, todo, spec, done, store, bar)
    result = _assemble(model, ind, X, grid, chunks, done, spec, parameters, resumed,
                       interrupted, store is not None, time.perf_counter() - start, client,
                       energy_tol, tau_choice)
    # This process's compilations (a cluster's workers compile on their own).
    result.provenance.timing = {k: round(v, 6) for k, v in clock.timing.items()}
    accuracy.warn(result.accuracy, method, what="the chaos map")
    return result


def _per_orbit(tau, model, method, t_check):
    """Whether ``tau`` asks for a step per orbit ("orbit"), refusing it
    where the steps of the orbits could not share the map's check times."""
    if not isinstance(tau, str):
        return False
    if tau != "orbit":
        raise ValueError(f"tau must be a positive number, None or 'orbit', got {tau!r}")
    if getattr(model, "kind", "flow") == "map" or not stepsize.pilots(method):
        raise ValueError(f"tau='orbit' chooses the step of a splitting scheme per orbit; "
                         f"{model.name} by {method!r} has no such step (give a number or None)")
    if t_check is not None and np.ndim(t_check) != 0:
        raise ValueError("tau='orbit' needs check times on the grid of its unit step: give "
                         "t_check as a count or None, not times")
    return True


def _choose_step(model, X, t_end, method, method_options, t_check, escape_radius, ind,
                 configured, k, seed, per_orbit=False):
    """The map's step from a pilot on a sample of its orbits
    (:func:`varint.stepsize.choose_step` with the map defaults: scheme
    :data:`MAP_SCHEME` unless one is given, tolerance
    :func:`pilot_tolerance` of the indicator, quantile
    :data:`MAP_QUANTILE`), or with ``per_orbit`` each orbit's from its own
    pilot (:func:`varint.stepsize_orbits.choose_steps`: the unit step, the
    divisors and the choice)."""
    if stepsize.pilots(method):
        method_options.setdefault("scheme", MAP_SCHEME)
    if escape_radius is not None:
        model = copy.copy(model)
        model.escape_radius = escape_radius
    common = {"scheme": method_options.get("scheme"), "seed": seed, "k": k,
              "renorm": ind.renorm, "accumulator": ind.accumulator_for(configured),
              "cap": None if t_check is None or np.ndim(t_check) == 0 else float(t_check[0])}
    if per_orbit:
        return stepsize_orbits.choose_steps(model, X, t_end, pilot_tolerance(ind), **common)
    return stepsize.choose_step(model, X, t_end, pilot_tolerance(ind), method=method,
                                quantile=MAP_QUANTILE, **common)


def _describe_options(options):
    return {k: (v.describe() if callable(getattr(v, "describe", None)) else v)
            for k, v in options.items()}


def _bar(progress, total, initial):
    progress = check.flag(progress, "progress")
    if progress is None:
        import sys

        progress = sys.stderr.isatty()
    if not progress:
        return contextlib.nullcontext(None)
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc="chaos_map", unit="orbit", leave=False)


def _run_local(client, model, X, chunks, todo, spec, done, store, bar):
    """Chunks one after the other in this process; each is parallel over its
    orbits. Returns whether Ctrl-C stopped the map (inside a chunk, its run
    stops at once; between chunks, the finished ones are kept)."""
    try:
        for c in todo:
            idx = chunks[c]
            chunk = run_chunk(model, X[idx], idx, spec)
            if chunk.interrupted:
                return True
            _finish(c, chunks[c], chunk, done, store, bar)
    except KeyboardInterrupt:
        return True
    return False


def _run_dask(client, model, X, chunks, todo, spec, done, store, bar):
    """Chunks as tasks on a Dask cluster, taken as they finish."""
    from distributed import as_completed

    futures = {client.submit(run_chunk, model, X[chunks[c]], chunks[c], spec,
                             pure=False): c for c in todo}
    try:
        for future in as_completed(futures):
            c = futures[future]
            _finish(c, chunks[c], future.result(), done, store, bar)
    except KeyboardInterrupt:
        client.cancel(list(futures))
        return True
    return False


def _finish(c, idx, chunk, done, store, bar):
    done[c] = chunk
    if store is not None:
        _save_chunk(store, c, idx, chunk)
    if bar is not None:
        bar.update(len(chunk.values))


def _total_cpu(times):
    """The sum of measured CPU times; None if one was not measured."""
    times = list(times)
    return None if any(t is None for t in times) else float(sum(times))


def _assemble(model, ind, X, grid, chunks, done, spec, parameters, resumed, interrupted, kept,
              wall, client, energy_tol, tau_choice):
    m, dim = X.shape
    values, t_stop = np.full(m, np.nan), np.full(m, np.nan)
    energy, max_energy, max_error = np.full(m, np.nan), np.full(m, np.nan), np.full(m, np.nan)
    status = np.zeros(m, dtype=np.int64)
    state = np.full((m, dim), np.nan)
    counts = {}
    for c, chunk in done.items():
        idx = chunks[c]
        values[idx], t_stop[idx], energy[idx] = chunk.values, chunk.t_stop, chunk.energy_error
        status[idx], state[idx] = chunk.status, chunk.state
        max_energy[idx], max_error[idx] = chunk.max_energy_error, chunk.max_error
        for key, n in chunk.counts.items():
            counts[key] = counts.get(key, 0) + int(n)
    failed = is_failure(status)
    if failed.any():
        codes = "; ".join(f"{int(n)}: {REASONS.get(int(s), f'status {int(s)}')}"
                          for s, n in zip(*np.unique(status[failed], return_counts=True),
                                          strict=True))
        warnings.warn(f"{int(failed.sum())} of {m} orbits failed ({codes}); their values are "
                      "NaN", RuntimeWarning, stacklevel=accuracy.user_stacklevel())
    if interrupted:
        warnings.warn(f"chaos map interrupted: {len(done)} of {len(chunks)} chunks finished"
                      + ("; they are kept in the checkpoint directory, call again to resume"
                         if kept else ""), RuntimeWarning,
                      stacklevel=accuracy.user_stacklevel())
    first = next(iter(done.values())).provenance if done else {}
    options = {"indicator": ind.name, "indicator_options": parameters["indicator_options"],
               "threshold": spec.threshold, "x0": parameters["x0"],
               "chunk_size": parameters["chunk_size"], "chunks": len(chunks),
               "chunks_resumed": resumed,
               "client": None if client is None else f"dask ({_cluster_threads(client)} threads)"}
    prov = Provenance(kind="chaos_map", model=model.describe(), x0=[], method=spec.method,
                      method_options=first.get("method_options", {}), tau=spec.tau,
                      t_end=spec.t_end, seed=spec.seed, options=options,
                      versions=first.get("versions", package_versions()), counts=counts,
                      wall_time=wall, tau_choice=dict(tau_choice),
                      code=first.get("code", identity.code_identity()),
                      machine=first.get("machine", identity.machine()),
                      cpu_time=_total_cpu(chunk.cpu_time for chunk in done.values()))
    failed = is_failure(status)
    with np.errstate(invalid="ignore"):
        accurate = ~failed & (max_error <= energy_tol)
    conserved = {"energy": max_energy}
    if not np.array_equal(max_error, max_energy, equal_nan=True):
        conserved["conserved quantities"] = max_error
    # When an orbit's error was largest is not kept (only the largest, up to
    # the time it was read at).
    verdict = accuracy.annotate(
        accuracy.Accuracy(energy_error=max_energy, conserved=conserved,
                          t_worst=np.full(m, np.nan), energy_tol=energy_tol,
                          accurate=accurate, tau=spec.tau),
        model, propagator_class(spec.method, model))
    empty = np.empty(0)
    return ChaosMapResult(
        t=spec.steps * spec.tau, energy_error=energy, state=state, provenance=prov,
        status=status, interrupted=interrupted, accuracy=verdict, indicator=ind.name,
        values=values,
        t_stop=t_stop, threshold=spec.threshold, x0=X,
        axes=None if grid is None else list(grid.axes),
        u=empty if grid is None else grid.u, v=empty if grid is None else grid.v,
        mask=np.zeros((0, 0), dtype=bool) if grid is None else grid.mask)
