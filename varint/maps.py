"""Chaos maps: one indicator for many initial conditions, on this machine or
on a Dask cluster.

A map evaluates an indicator — any of :data:`varint.INDICATORS` that has a
map value (SALI, GALI_k, X1, MEGNO, FLI, OFLI, local exponents, or one a
user registered) — for an (M, 2N) array of initial conditions or a grid on
a surface of section (:func:`varint.section_grid`). It uses the same
:class:`~varint.indicators.Indicator` objects and the same run as single
runs: the map's arguments are checked once into a
:class:`~varint.runspec.RunSpec` (:func:`varint.runspec.specify`), its τ
and check times fixed once, and every chunk is a
:class:`~varint.run.Run` of that specification over its orbits. A chunk is
one batch run of the compiled integrator, parallel over its orbits (the
serial kernel on threads over slices of them,
:func:`varint.threads.orbits_in_threads`), so nothing per orbit passes
through Python. The chunks run one
after the other here, or with a ``dask.distributed.Client`` on the cluster,
one task each, coming back as they finish (:mod:`varint.fanout`, shared
with ensembles).

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

import dataclasses
import logging
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
from . import accuracy, compiling, identity, step_agreement, step_cost, stepsize, stepsize_orbits
from .checkpoint import digest
from .fanout import (bar, client_label, cluster_threads, fan_out, total_cpu, warn_failures,
                     warn_interrupted, worker_threads)
from .indicators import INDICATORS, Indicator
from .methods import propagator_class
from .models.base import Model
from .protocol import STATUS_OK, Status, is_failure
from .results import ChaosMapResult, Provenance, package_versions
from .run import Run
from .runspec import RunSpec, check_seed, described, specify
from .grids import SectionGrid
from .lh_offset import offset_constant
from .state import initial_deviations
from .store import Invalid, Store

__all__ = ["chaos_map", "MAP_SCHEME", "MAP_PILOT_TOL", "pilot_tolerance"]

_log = logging.getLogger(__name__)

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
    """What every chunk of one map shares (sent to the workers): the run
    each chunk makes of its orbits (:meth:`RunSpec.without_orbits`: τ
    fixed, the check times as its output steps), how many deviation vectors
    each orbit draws, and the early-stopping threshold."""

    run: RunSpec
    k: int
    threshold: float | None
    #: Per orbit of the map, the divisor n of its step τ = run.tau / n
    #: (``tau="orbit"``, :mod:`varint.stepsize_orbits`); None: one step.
    divisions: np.ndarray | None = None

    @property
    def t_check(self):
        """The check times (the last one t_end)."""
        return self.run.steps * self.run.tau


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


def run_chunk(x0, indices, spec, reference=None):
    """One chunk of a map: the orbits ``x0`` (their ``indices`` in the whole
    map) as one batch run of the map's :class:`RunSpec`, stopping early at
    its check times; ``reference``: their rows of the map's
    :class:`~varint.accuracy.Reference`, or None (computed again).
    """
    if spec.divisions is not None:
        return stepsize_orbits.run_grouped(run_chunk, x0, indices, spec, reference)
    ind, model = spec.run.indicator, spec.run.model
    cpu = time.process_time()
    with worker_threads() as cancelled, warnings.catch_warnings():
        # Failed orbits are counted by the map, which warns once.
        warnings.simplefilter("ignore", RuntimeWarning)
        W0 = initial_deviations(model.dim, spec.k, len(x0), spec.run.seed, indices)
        job = Run(spec.run.for_orbits(x0, reference), deviations=W0, progress=False,
                  errors="flag")

        def record(rows):
            rec = job.record(rows)
            errors = [v for k, v in rec.items()
                      if k == "energy_error" or k.startswith("conserved_error:")]
            return {"value": ind.scalar(rec, model, job.options),
                    "energy_error": rec["energy_error"], "max_error": np.max(errors, axis=0)}

        def decide(rec):
            return ind.settled(rec["value"], spec.threshold)

        records, stop, _ = job.drive(record, None if spec.threshold is None else decide,
                                     cancelled, stack=False)
    state = job.state
    n_done = len(records)
    # Read each orbit at the last output it was active at: where it was
    # decided, else the last one reached.
    at = np.full(len(x0), n_done - 1)
    stopped = state.status == Status.DECIDED
    at[stopped] = np.searchsorted(job.steps[:n_done], state.fail_step[stopped])
    values, energy, *largest = _read_at(records, at)
    t_stop = np.where(state.status != STATUS_OK, state.fail_step, state.step) * spec.run.tau
    return _Chunk(values=values, t_stop=t_stop, status=state.status.copy(), energy_error=energy,
                  state=state.x.copy(), max_energy_error=largest[0], max_error=largest[1],
                  counts=dict(state.counts),
                  provenance={"method_options": job.propagator.describe(),
                              "versions": job.versions(), "code": job.code,
                              "machine": job.machine},
                  interrupted=stop == "interrupted",
                  cpu_time=None if cancelled is not None else time.process_time() - cpu)


def _read_at(records, at):
    """Per orbit ``m`` of a chunk's ``records`` (:class:`~varint.records.Records`
    of the map's record: "value", "energy_error", "max_error"): the value
    and the energy error at output ``at[m]``, and the largest energy error
    and error of any conserved quantity up to it (NaN ignored; NaN where
    every one is NaN, or without outputs).

    Read block by block, as they were recorded: the blocks are not joined
    into arrays of every output first (a copy of all of them). The largest
    of the blocks' largest (``np.fmax``, which skips NaN) is the largest of
    all outputs: the same numbers as ``np.nanmax`` of the joined arrays.
    """
    m = len(at)
    picked = {key: np.full(m, np.nan) for key in ("value", "energy_error")}
    largest = {key: np.full(m, np.nan) for key in ("energy_error", "max_error")}
    # Without early stopping every orbit is read at the last output: no
    # mask of the outputs after an orbit's.
    last = len(records) - 1
    every = bool(np.all(at == last))
    for first, block in records.blocks():
        n = len(block["value"])
        here = np.flatnonzero((at >= first) & (at < first + n))
        if here.size:
            for key, out in picked.items():
                out[here] = block[key][at[here] - first, here]
        for key, out in largest.items():
            part = block[key]
            if not every:
                part = np.where((first + np.arange(n))[:, None] <= at[None, :], part, np.nan)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # failed before the first
                np.fmax(out, np.nanmax(part, axis=0), out=out)
    return picked["value"], picked["energy_error"], largest["energy_error"], \
        largest["max_error"]


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
    t_end, checks_at = spec.run.t_end, spec.t_check
    t = a["t_stop"]
    ok = np.where(status == STATUS_OK, t == checks_at[-1],
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


def chaos_map(model: Model, initial_conditions: ArrayLike | SectionGrid,
              indicator: str | Indicator = "sali", *, t_end: float, tau: float | str | None = None,
              method: str = "tm", threshold: float | str | None = "default", seed: int = 0,
              t_check: int | ArrayLike | None = None, chunk_size: int | None = None,
              client: Any = None, checkpoint: str | os.PathLike[str] | None = None,
              progress: bool | None = None, escape_radius: float | None = None,
              energy_tol: float | None = None, time_transform: str | None = "auto",
              **options: Any) -> ChaosMapResult:
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
    tau : float, "orbit" or None, optional
        Step (renormalisation interval). By default the method's pilot
        chooses it (:func:`varint.stepsize.choose_step` on a sample of the
        orbits) for :data:`MAP_SCHEME` unless a ``scheme`` is given, to an
        energy error of :func:`pilot_tolerance` (:data:`MAP_PILOT_TOL`, or the
        indicator's own ``map_tolerance``), and the result records the
        choice (``provenance.tau_choice``); one iteration for a map model.
        ``"orbit"``: each orbit its own step, from its own pilot to the same
        tolerance or, judged by the map's indicator, a larger step whose
        value agrees with a smaller one's (:mod:`varint.stepsize_orbits`);
        the steps divide one unit
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
    time_transform : "auto", None or "log"
        "log": FLI maps with steps that follow the orbit, the logarithmic
        Hamiltonian of :class:`varint.time_transform.LogHamiltonian`
        (refused for other indicators, backends and schemes with a
        corrector or processor, early stopping, ``t_check``, ``client``,
        ``checkpoint``). ``tau`` is then the step h in the fictitious time
        s, by default the largest h at which the pilot orbits' FLI agrees
        with that at h/2 to the map's t_end (values within 0.05 dex times
        t_pilot/t_end, or both chaotic at ln(1000 t)), with
        their energy errors within ten times ``energy_tol``
        (:func:`varint.time_transform_step.agreeing_h`,
        ``provenance.tau_choice``), each orbit whose own energy error
        exceeds ``energy_tol`` then run again at h/2, h/4, … h/16
        (:func:`varint.time_transform_step.retried`; each orbit's step in
        ``provenance.tau_choice["h_orbit"]``, its halvings in ``"levels"``)
        (the energy pilot's h for every orbit, with a warning,
        where none does); the options ``scheme`` (a two-part
        scheme without corrector or processor, default ABA864), ``offset``
        (δ of C = E + δ; by default the cheapest of a short ladder priced
        by the pilot, :func:`varint.time_transform_step.agreeing_offset`,
        ``provenance.tau_choice["offset"]``; a given δ is kept) and
        ``every`` (the physical time between
        normalisations of the vector, default 10). "auto" (the default): an
        FLI map with no τ, scheme or other option, of a model the LH takes,
        whose U = C − V varies by :data:`U_SPREAD_MIN` or more over the
        pilot orbits (their starts, and δ where a kinetic A turns), prices the LH at its agreeing h against
        constant steps at theirs (the largest multiple of the energy
        pilot's step at which the FLI agrees with that at half of it) and
        runs the cheaper (:func:`_cheaper_steps`; the LH's method is
        "tm+log", and the ``varint.maps`` logger says so); every other map
        keeps the energy pilot's constant step. None: constant steps
        always, by the energy pilot.

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
    auto = isinstance(time_transform, str) and time_transform == "auto"
    if time_transform is not None and not auto:
        return _log_map(model, initial_conditions, indicator, t_end=t_end, tau=tau,
                        method=method, threshold=threshold, seed=seed, t_check=t_check,
                        chunk_size=chunk_size, client=client, checkpoint=checkpoint,
                        progress=progress, escape_radius=escape_radius,
                        energy_tol=energy_tol, time_transform=time_transform, **options)
    client = check.dask_client(client)
    grid = initial_conditions if isinstance(initial_conditions, SectionGrid) else None
    if grid is not None and grid.states.size == 0:
        raise ValueError("the section grid holds no allowed point at this energy")
    # The map draws orbit m's vectors from [seed, m]: a seed is needed.
    seed = check_seed(seed, none=False)
    per_orbit = _per_orbit(tau, model, method, t_check)
    spec = specify(model, initial_conditions if grid is None else grid.states, indicator,
                   t_end, None if per_orbit else tau, method=method, t_out=t_check, seed=seed,
                   escape_radius=escape_radius, energy_tol=energy_tol,
                   what="initial_conditions" if grid is None else "the section grid's states",
                   kernels_what="initial condition", t_out_name="t_check", **options)
    if spec.single:
        raise ValueError("initial_conditions must have shape (M, 2N) (one row per orbit), "
                         f"got shape {np.asarray(initial_conditions).shape}")
    model, X, ind = spec.model, spec.x0, spec.indicator
    m = len(X)
    # The map's per-orbit results (values, times, status, errors, states).
    check.check_memory(check.array_bytes((m, 2 * X.shape[1] + 8)),
                       f"a chaos map of {m} orbits of {model.name}")
    if ind.scalar is None:
        raise ValueError(f"indicator {ind.name!r} has no map value (one number per orbit); "
                         "maps take: " + ", ".join(n for n, i in INDICATORS.items()
                                                  if i.scalar is not None))
    k = ind.vectors(model, spec.options, None)
    limit = _threshold(threshold, spec)
    chunk_size = _chunk_size(chunk_size, m, client)
    progress = check.flag(progress, "progress")
    clock = compiling.Clock(f"the {ind.name} map of {model.name} by {spec.method}", progress)
    stepped = divisions = None
    if auto and _log_candidate(spec, ind, tau, method, options, threshold, t_check, client,
                               checkpoint, escape_radius):
        h_choice, stepped = _cheaper_steps(spec, k, clock)
        if h_choice is not None:
            return _log_map(model, initial_conditions, ind.name, t_end=t_end,
                            tau=h_choice["h"], method=method, threshold=threshold, seed=seed,
                            t_check=None, chunk_size=chunk_size, client=None, checkpoint=None,
                            progress=progress, escape_radius=None, energy_tol=energy_tol,
                            time_transform="log", h_choice=h_choice, clock=clock)
    if stepped is None:
        spec, divisions = _with_step(spec, k, clock, per_orbit)
    else:
        spec = stepped
    shared = _Spec(run=spec.without_orbits(), k=k, threshold=limit, divisions=divisions)
    # A fixed shuffle spreads islands and chaotic seas evenly over chunks
    # and over the threads within a chunk, whose orbits stop at different
    # times; values do not depend on it (see the module docstring).
    order = np.random.default_rng(20100927).permutation(m)
    chunks = [order[i:i + chunk_size] for i in range(0, m, chunk_size)]
    parameters = {"kind": "chaos_map", "model": model.describe(), "x0": digest(X),
                  "indicator": ind.name, "indicator_options": spec.options,
                  "threshold": limit, "t_end": spec.t_end, "tau": spec.tau,
                  "t_check": digest(spec.steps), "method": spec.method,
                  "method_options": described(spec.method_options), "seed": seed,
                  "chunk_size": int(chunk_size), "escape_radius": spec.escape_radius,
                  "versions": package_versions(), "code": identity.source_digest()}
    if divisions is not None:
        parameters["tau_divisions"] = digest(divisions)
    store = None if checkpoint is None else Store(checkpoint, "chaos map", parameters)
    done = {} if store is None else _resume(store, chunks, shared, X.shape[1])
    resumed = len(done)
    todo = [c for c in range(len(chunks)) if c not in done]

    def keep(c, chunk):
        done[c] = chunk
        if store is not None:
            _save_chunk(store, c, chunks[c], chunk)
        return len(chunk.values)

    with bar(progress, m, sum(len(chunks[c]) for c in done), "chaos_map", "orbit") as shown, \
            clock.part("run"):
        # Each chunk's reference is its rows of the map's: the initial
        # energies are computed once.
        interrupted = fan_out(client, todo, run_chunk, lambda c: (
            # np.take: the rows gathered as X[idx] does, without numpy's
            # fancy indexing of a 2-D array row by row (slower at 1e6 rows).
            np.take(X, chunks[c], axis=0), chunks[c], shared, spec.reference.rows(chunks[c])),
            keep, shown)
    result = _assemble(spec, X, grid, chunks, done, limit, parameters, resumed, interrupted,
                       store is not None, time.perf_counter() - start, client)
    # This process's compilations (a cluster's workers compile on their own).
    result.provenance.timing = {k: round(v, 6) for k, v in clock.timing.items()}
    accuracy.warn(result.accuracy, spec.method, what="the chaos map")
    return result


#: The logarithmic Hamiltonian is considered only where U = C − V at the
#: map's initial conditions spans at least this ratio (:func:`_u_spread`):
#: the physical step it takes varies as 1/U. ``studies/lh_defaults.py``:
#: Hénon–Heiles 1.12, the cored potentials 2.0 (R_c = 0.3) to 2.7
#: (R_c = 0.03), the Sun–Jupiter section 2.8.
U_SPREAD_MIN = 1.5


def _log_candidate(spec, ind, tau, method, options, threshold, t_check, client, checkpoint,
                   escape_radius):
    """Whether a map ``spec`` with ``time_transform="auto"`` prices the
    logarithmic Hamiltonian against constant steps before either step is
    chosen (:func:`_cheaper_steps`): an FLI map with every default the LH map
    keeps (no τ, scheme or other option, the TM method, no early stopping,
    check times, cluster, checkpoint or escape radius), of a model of the
    form it takes, whose U varies by :data:`U_SPREAD_MIN` or more over the
    pilot's initial conditions. The cheap tests come first: every other map
    builds nothing for it, and keeps the energy pilot's constant step as
    before."""
    model = spec.model
    if (ind.name != "fli" or tau is not None or method != "tm" or options
            or threshold not in ("default", None) or t_check is not None
            or client is not None or checkpoint is not None or escape_radius is not None
            or getattr(model, "kind", "flow") == "map"):
        return False
    pilot = spec.x0[step_agreement.pilot_sample(spec.x0, spec.seed)]
    # The spread counted as for a kinetic A (a lower denominator) bounds the
    # one counted without: below the threshold the model is no candidate
    # whatever its form, and SymPy, which reading the form takes, stays
    # unloaded (~0.35 s of a first Hénon–Heiles map, studies/startup.py).
    bound = _u_spread(model, pilot, kinetic=True)
    if bound < U_SPREAD_MIN:
        return False
    # Only now: the LH's module imports SymPy, which a map that keeps its
    # constant step never needs.
    from .time_transform import refuse

    try:
        parts, _ = refuse(model)
    except ValueError:
        return False
    spread = bound if parts[4].kind == "free" else _u_spread(model, pilot)
    return spread >= U_SPREAD_MIN


def _u_spread(model, X, kinetic=False):
    """max U / min U over the states ``X``, U = C − V(q) with C of
    :class:`~varint.time_transform.LogHamiltonian` (δ = max(−E, 1)): how
    much its physical step would vary between them (inf where U ≤ 0).
    With a ``kinetic`` A ≥ 0, U = A + δ ≥ δ along each orbit, δ where it
    turns (A = 0): the lowest U counted is δ. (Without it the cored race
    of ``studies/map_steps.py``, whose orbits all start fast at the bottom
    of the core and turn at r ≈ 1, measured 1.4 and was never priced.)"""
    n = X.shape[1] // 2
    with np.errstate(all="ignore"):
        E = np.asarray(model.conserved(X)["energy"], dtype=float)
        C = offset_constant(E, None)
        U = C - np.asarray(model.potential(X[:, :n]), dtype=float)
    if not (np.all(np.isfinite(U)) and np.all(U > 0)):
        return math.inf
    return float(U.max() / (min(U.min(), float(np.min(C - E))) if kinetic else U.min()))


def _cheaper_steps(spec, k, clock):
    """The cheaper of the LH map and the constant-step map under the same
    guarantee, for a map ``spec`` whose step is not chosen yet: each one's
    largest step at which the pilot orbits' FLI agrees with that at half
    the step (:mod:`varint.step_agreement`: the LH's
    :func:`~varint.time_transform_step.agreeing_h`; the constant step's
    :func:`~varint.step_agreement.agreeing_tau` with :data:`MAP_SCHEME`;
    both by one rule, :func:`~varint.step_agreement.map_verdict`, the FLI
    values to the map's t_end (the constant ladder was once judged by the
    verdict at the pilot's t, which favoured constant steps on a map much
    longer than its pilot; ``studies/ladder_rule.py``); both
    with energy errors within ``energy_tol``, the LH's pilot 10 times that:
    its map retries each orbit to ``energy_tol``),
    priced as force evaluations per orbit and unit of time times their
    cost, each stepper's from its emitted source
    (:func:`varint.step_cost.log_gradient_cost`,
    :func:`~varint.step_cost.constant_gradient_cost`: its operations,
    priced by fixed tables of the LH's scalar code or its lanes, as its map
    will run (:meth:`~varint.time_transform.LogHamiltonian.runs_in_lanes`;
    its descent is stopped at its lowest price), and of the constant
    step's lanes, vectorised or not, so the choice does not depend on the
    timing of the run that makes it). The two pilots run in order of price
    (:class:`~varint.step_agreement.ConstantLadder`), each choice priced
    with the pilot it still has to run (:func:`_pilot_share`): before each
    rung of the LH's descent is judged, every constant step that costs less
    is, and a constant step that passed, whose map is cheaper than the LH
    rung's map and pilot run together, stops the LH's descent (its finer
    rungs cost more); once the LH passes, the constant steps whose map and
    pilot run together cost less than the LH's map (retries counted) are
    judged. The choice is
    that of the LH's pilot followed by the constant one stopped at its
    price over 1 + the pilot share, with fewer runs. Returns ``(h_choice,
    stepped)``: the LH's choice (with the ``prices``) and None, or None and
    ``spec`` at the constant step chosen by agreement (with the map's check
    steps, :func:`_with_step`), or None and None where the LH's FLI agrees
    at no step tried and no constant step agreed below its prices, or the
    constant step's at none whose price is below the LH's and the LH's is
    not cheaper (the map then takes the energy pilot's constant step, as
    every other map)."""
    from .time_transform import MIN_LANES
    from .time_transform_step import RETRY_CEILING, agreeing_offset

    model, X = spec.model, spec.x0
    with clock.part("pilot"):
        lh = _log_hamiltonian(model, LOG_MAP_OPTIONS["scheme"], None)
        # The LH's lowest price (over lanes where the map has orbits enough
        # for them) stops its descent; its map is priced as it will run.
        log_cost, _ = step_cost.log_gradient_cost(lh, lanes=len(X) >= MIN_LANES)
        constant_cost, _ = step_cost.constant_gradient_cost(
            model, MAP_SCHEME, k, spec.indicator.accumulator_for(spec.options))
        judge = stepsize_orbits.indicator_judge(spec.indicator, model, spec.options,
                                                pilot_tolerance(spec.indicator), spec.energy_tol)
        ladder = step_agreement.ConstantLadder(
            model, X, spec.t_end, scheme=MAP_SCHEME, seed=spec.seed, k=k,
            renorm=spec.indicator.renorm,
            accumulator=spec.indicator.accumulator_for(spec.options), value=judge.value,
            quantile=MAP_QUANTILE, ceiling=spec.energy_tol, agree=step_agreement.map_verdict)

        share = _pilot_share(spec)

        def beaten(rate):
            # Pilots ordered by price: before each LH rung is judged, the
            # constant steps that cost less are. A constant step that passed
            # has nothing left to run but the map; the LH rung still has its
            # h/2 run to make, so it stops the LH's descent once its map is
            # cheaper than the LH's map and that run together.
            return ladder.cheaper_than(rate, log_cost / constant_cost, 1.0 + share)

        # The LH map retries each orbit to energy_tol itself (_log_map):
        # its pilot's ceiling is looser, its price counts the retries; its
        # offset δ is the cheapest the pilot priced.
        # Both pilots run the same orbits: one reference, and (one vector
        # each) the same vectors, drawn once; the LH's energies at the
        # orbits' starts serve every δ and the lanes' choice.
        starts = lh.starts(X)
        chosen, h, choice = agreeing_offset(lh, X, spec.t_end, quantile=MAP_QUANTILE,
                                       ceiling=RETRY_CEILING * spec.energy_tol, seed=spec.seed,
                                       every=LOG_MAP_OPTIONS["every"], retry=spec.energy_tol,
                                       stop_above=beaten, reference=ladder.reference,
                                       deviations=ladder.W0[:, :, 0] if k == 1 else None,
                                       starts=starts)
        stopped = h is None and ladder.rate is not None
        if h is None and not stopped:
            return None, None
        if not stopped:
            log_cost, _ = step_cost.log_gradient_cost(
                chosen, lanes=chosen.runs_in_lanes(X, spec.t_end, h, starts=starts))
        log_price = math.inf if stopped else choice["gradient_rate"] * log_cost
        # The LH's pilot is spent, its map is what is left; a constant rung
        # still to be judged has its τ/2 run to make before its map: it is
        # judged only while both cost less than the LH's map.
        ladder.advance(log_price / constant_cost / (1.0 + share))
        tau, constant = ladder.result()
    prices = {"log": None if stopped else log_price,
              "constant": constant["gradient_rate"] * constant_cost,
              "log_gradient_cost": log_cost, "constant_gradient_cost": constant_cost,
              "pilot_share": share}
    if tau is None or log_price < prices["constant"]:
        choice.update(prices=prices, constant=constant)
        _log.info("chaos_map: the logarithmic-Hamiltonian step (h = %.4g) is predicted "
                  "cheaper than constant steps of %s (%s) on the FLI map of %s: running it "
                  "(time_transform=None keeps constant steps)", h, MAP_SCHEME,
                  "none agrees at a lower price" if tau is None else
                  f"tau = {tau:.4g}, {prices['constant'] / log_price:.3g} times the price",
                  model.name)
        return choice, None
    if stopped:
        choice.update(summary="the LH's descent stopped or found no h: constant steps "
                              "agreed at a lower price than its steps")
    constant.update(prices=prices, log=choice)
    stepped = dataclasses.replace(
        spec, method_options={**spec.method_options, "scheme": MAP_SCHEME}).with_step(
            tau, constant, indicator_times=False)
    return None, _check_steps(stepped)


def _pilot_share(spec):
    """The price of a rung's pilot run in units of the map's run at the same
    step, for the defaults' switch (:func:`_cheaper_steps`): judging a rung
    of either ladder (the LH's or the constant step's) runs its pilot
    orbits at half its step to the pilot's time, 2·P·t_p force-evaluation
    units of its rate for P pilot orbits and a pilot time t_p, against
    M·t_end for the map's M orbits. A map of few or short orbits pays for
    its pilot more than a large one, so a rung whose run and pilot together
    cost more than the other stepper's map is not judged."""
    pilots = len(step_agreement.pilot_sample(spec.x0, spec.seed))
    return 2.0 * pilots * min(spec.t_end, stepsize.PILOT_T) / (len(spec.x0) * spec.t_end)


def _threshold(threshold, spec):
    """The early-stopping threshold of ``threshold=`` (see :func:`chaos_map`)."""
    if isinstance(threshold, str) and threshold == "default":
        return spec.indicator.default_threshold(spec.model, spec.options)
    if threshold is None:
        return None
    if (isinstance(threshold, bool) or not isinstance(threshold, numbers.Real)
            or not np.isfinite(threshold)):
        raise ValueError(f"threshold must be a finite number, None or 'default', "
                         f"got {threshold!r}")
    return float(threshold)


def _chunk_size(chunk_size, m, client):
    """Orbits per chunk: as given, or :func:`_default_chunk_size`."""
    if chunk_size is None:
        return _default_chunk_size(m, 1 if client is None else cluster_threads(client))
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) \
            or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    return int(chunk_size)


def _resume(store, chunks, shared, dim):
    """The chunks of this map its checkpoint directory holds, valid
    (:func:`_load_chunk`), by number."""
    store.manifest("map.json")
    done = {}
    for c, idx in enumerate(chunks):
        chunk = _load_chunk(store, c, idx, shared, dim)
        if chunk is not None:
            done[c] = chunk
    return done


def _with_step(spec, k, clock, per_orbit=False):
    """``spec`` with the map's τ and check steps, and the orbits' divisors
    of τ (None but for ``tau="orbit"``): τ as given, or from a pilot
    (:func:`_with_pilot_step`), or each orbit's from its own pilot
    (``per_orbit``, τ the unit its steps divide); the check times of ``t_check``, or log-spaced from
    :data:`FIRST_CHECK_STEP` steps on (and t_end). Every chunk runs these
    (the map's τ is chosen here, once)."""
    divisions = None
    if per_orbit or spec.tau is None:
        with clock.part("pilot"):
            spec, divisions = _with_pilot_step(spec, k, per_orbit)
    else:
        spec = spec.with_step(spec.tau, indicator_times=False)
    if spec.t_out is None:
        spec = _check_steps(spec)
    return spec, divisions


def _check_steps(spec):
    """``spec`` with its log-spaced check steps from :data:`FIRST_CHECK_STEP`
    on (and the last): earlier checks cost more than they could stop."""
    steps = spec.steps
    return dataclasses.replace(
        spec, steps=steps[(steps >= FIRST_CHECK_STEP) | (steps == steps[-1])])


def _with_pilot_step(spec, k, per_orbit=False):
    """``spec`` with the map's step, from a pilot with the map defaults
    (scheme :data:`MAP_SCHEME` unless one is given, tolerance
    :func:`pilot_tolerance` of the indicator), and each orbit's divisor of
    it (None unless ``per_orbit``): one step for all from a sample of the
    orbits (:func:`varint.stepsize.choose_step`, quantile
    :data:`MAP_QUANTILE`), or with ``per_orbit`` the unit step of
    ``tau="orbit"`` and each orbit's divisor from its own pilot
    (:func:`varint.stepsize_orbits.choose_steps`)."""
    method_options = dict(spec.method_options)
    if stepsize.pilots(spec.method):
        method_options.setdefault("scheme", MAP_SCHEME)
    t_check = spec.t_out
    common = {"scheme": method_options.get("scheme"), "seed": spec.seed, "k": k,
              "renorm": spec.indicator.renorm,
              "accumulator": spec.indicator.accumulator_for(spec.options),
              "cap": None if t_check is None or np.ndim(t_check) == 0 else float(t_check[0])}
    tolerance = pilot_tolerance(spec.indicator)
    divisions = None
    if per_orbit:
        judge = stepsize_orbits.indicator_judge(spec.indicator, spec.model, spec.options,
                                                tolerance, spec.energy_tol)
        tau, divisions, tau_choice = stepsize_orbits.choose_steps(
            spec.model, spec.x0, spec.t_end, tolerance, judge=judge, **common)
    else:
        tau, tau_choice = stepsize.choose_step(spec.model, spec.x0, spec.t_end, tolerance,
                                               method=spec.method, quantile=MAP_QUANTILE,
                                               **common)
    spec = dataclasses.replace(spec, method_options=method_options).with_step(
        tau, tau_choice, indicator_times=False)
    return spec, divisions


def _per_orbit(tau, model, method, t_check):
    """Whether ``tau`` asks for a step per orbit ("orbit"), refusing it
    where the steps of the orbits could not share the map's check times."""
    if not isinstance(tau, str):
        return False
    if tau != "orbit":
        raise ValueError(f"tau must be a positive number, None or 'orbit', got {tau!r}")
    if getattr(model, "kind", "flow") == "map" or not stepsize.pilots(method):
        raise ValueError(f"tau='orbit' chooses the step of a splitting scheme per orbit; "
                         f"{getattr(model, 'name', model)} by {method!r} has no such step "
                         "(give a number or None)")
    if t_check is not None and np.ndim(t_check) != 0:
        raise ValueError("tau='orbit' needs check times on the grid of its unit step: give "
                         "t_check as a count or None, not times")
    return True


def _in_map_order(m, dim, chunks, done):
    """The chunks' per-orbit arrays (:data:`_CHUNK_ARRAYS`) put back in the
    map's order of orbits: NaN (status 0) for orbits of chunks not done.

    Where every orbit is done, gathered by the inverse of the chunks'
    shuffle (``np.take``) instead of written through the chunks' indices
    (numpy's fancy indexing of a 2-D array, row by row): the same numbers;
    the assembly of a 1e6-orbit GPU map 0.16 -> 0.13 CPU s
    (``studies/results/gpu23/stages_1e6_warm1.md``)."""
    kinds = {"f": float, "i": np.int64}
    if done and sum(len(chunks[c]) for c in done) == m:
        order = np.concatenate([chunks[c] for c in done])
        inverse = np.empty(m, dtype=np.int64)
        inverse[order] = np.arange(m)
        out = []
        for name, kind in _CHUNK_ARRAYS.items():
            parts = [np.asarray(getattr(chunk, name)) for chunk in done.values()]
            joined = parts[0] if len(parts) == 1 else np.concatenate(parts)
            out.append(np.take(joined, inverse, axis=0).astype(kinds[kind], copy=False))
        return tuple(out)
    out = []
    for name, kind in _CHUNK_ARRAYS.items():
        shape = (m, dim) if name == "state" else (m,)
        arr = np.zeros(shape, dtype=np.int64) if kind == "i" else np.full(shape, np.nan)
        for c, chunk in done.items():
            arr[chunks[c]] = getattr(chunk, name)
        out.append(arr)
    return tuple(out)


def _assemble(spec, X, grid, chunks, done, threshold, parameters, resumed, interrupted, kept,
              wall, client):
    model, ind = spec.model, spec.indicator
    m, dim = X.shape
    values, t_stop, status, energy, state, max_energy, max_error = _in_map_order(
        m, dim, chunks, done)
    counts = {}
    for chunk in done.values():
        for key, n in chunk.counts.items():
            counts[key] = counts.get(key, 0) + int(n)
    warn_failures(status, "orbits", "their values are NaN")
    if interrupted:
        warn_interrupted("chaos map", len(done), len(chunks), "chunks", kept)
    first = next(iter(done.values())).provenance if done else {}
    options = {"indicator": ind.name, "indicator_options": parameters["indicator_options"],
               "threshold": threshold, "x0": parameters["x0"],
               "chunk_size": parameters["chunk_size"], "chunks": len(chunks),
               "chunks_resumed": resumed,
               "client": client_label(client)}
    prov = Provenance(kind="chaos_map", model=model.describe(), x0=[], method=spec.method,
                      method_options=first.get("method_options", {}), tau=spec.tau,
                      t_end=spec.t_end, seed=spec.seed, options=options,
                      versions=first.get("versions", package_versions()), counts=counts,
                      wall_time=wall, tau_choice=dict(spec.tau_choice),
                      code=first.get("code", identity.code_identity()),
                      machine=first.get("machine", identity.machine()),
                      cpu_time=total_cpu(chunk.cpu_time for chunk in done.values()))
    failed = is_failure(status)
    with np.errstate(invalid="ignore"):
        accurate = ~failed & (max_error <= spec.energy_tol)
    conserved = {"energy": max_energy}
    if not np.array_equal(max_error, max_energy, equal_nan=True):
        conserved["conserved quantities"] = max_error
    # When an orbit's error was largest is not kept (only the largest, up to
    # the time it was read at).
    verdict = accuracy.annotate(
        accuracy.Accuracy(energy_error=max_energy, conserved=conserved,
                          t_worst=np.full(m, np.nan), energy_tol=spec.energy_tol,
                          accurate=accurate, tau=spec.tau),
        model, propagator_class(spec.method, model))
    if spec.tau_choice.get("rule") == "indicator":
        verdict.notes["step"] = spec.tau_choice["summary"]
    empty = np.empty(0)
    return ChaosMapResult(
        t=spec.steps * spec.tau, energy_error=energy, state=state, provenance=prov,
        status=status, interrupted=interrupted, accuracy=verdict, indicator=ind.name,
        values=values,
        t_stop=t_stop, threshold=threshold, x0=X,
        axes=None if grid is None else list(grid.axes),
        u=empty if grid is None else grid.u, v=empty if grid is None else grid.v,
        mask=np.zeros((0, 0), dtype=bool) if grid is None else grid.mask,
        log_scale=ind.log_scale)


#: The options of a ``time_transform="log"`` map besides those of
#: :func:`chaos_map` itself, and their defaults (``None``: the rule of
#: :class:`~varint.time_transform.LogHamiltonian`).
LOG_MAP_OPTIONS = {"scheme": "ABA864", "offset": None, "every": 10.0, "backend": "cpu"}


def _log_map(model, initial_conditions, indicator, *, t_end, tau, method, threshold, seed,
             t_check, chunk_size, client, checkpoint, progress, escape_radius, energy_tol,
             time_transform, h_choice=None, clock=None, **options):
    """The FLI map of :func:`chaos_map` with ``time_transform="log"``: the
    orbits in chunks (the map's fixed shuffle, :func:`_chunk_size`), each
    chunk one call of :meth:`LogHamiltonian.outputs
    <varint.time_transform.LogHamiltonian.outputs>` from orbit m's vector of
    ``default_rng([seed, m])``, so a value does not depend on the chunking.
    Everything it does not support is refused in one line before any work.
    A failed orbit's value is NaN; its status is the map's
    ``INTEGRATOR_FAILED`` for the LH's own stops (U ≤ 0, the step budget),
    whose reasons ``provenance.options["lh_failures"]`` counts, or the
    :class:`~varint.protocol.Status` the step reported, and its ``t_stop``
    the time its last completed step reached. The result carries the final
    states, their energy errors and the accuracy verdict of every map
    (:func:`_log_verdict`, warning as :func:`chaos_map` does), and in
    ``provenance.timing`` the seconds of compilation, pilot and run kept
    apart, as every map's: ``clock`` is the defaults' (:func:`chaos_map`,
    whose pilot priced this map against constant steps), else one of its
    own."""
    from .time_transform import TIME_TRANSFORMS, describe, refuse
    from .time_transform_step import RETRY_CEILING, agreeing_offset, choose_h, retried

    if time_transform not in TIME_TRANSFORMS:
        raise ValueError(f"time_transform must be None or one of {list(TIME_TRANSFORMS)}, "
                         f"got {time_transform!r}")
    name = indicator.name if isinstance(indicator, Indicator) else indicator
    if name != "fli":
        raise ValueError(f"time_transform='log' computes FLI maps only, got indicator {name!r}")
    h = None if tau is None else check.positive_float(tau, "tau (the fictitious step h)")
    t_end = check.end_time(t_end)
    model = check.model(model)
    unknown = sorted(set(options) - set(LOG_MAP_OPTIONS))
    if unknown:
        raise ValueError(f"time_transform='log' takes the options {list(LOG_MAP_OPTIONS)}, "
                         f"got {unknown[0]!r}")
    opts = {**LOG_MAP_OPTIONS, **options}
    if opts["backend"] != "cpu":
        raise ValueError(f"time_transform='log' runs on the CPU only, got backend "
                         f"{opts['backend']!r}")
    every = check.positive_float(opts["every"], "every")
    progress = check.flag(progress, "progress")
    for what, value, allowed in (("method", method, "tm"),
                                 ("threshold", threshold, "default or None"),
                                 ("t_check", t_check, None), ("client", client, None),
                                 ("checkpoint", checkpoint, None),
                                 ("escape_radius", escape_radius, None)):
        fine = (value in ("default", None) if what == "threshold"
                else value is None if allowed is None else value == allowed)
        if not fine:
            raise ValueError(f"time_transform='log' does not take {what}={value!r} (yet): "
                             f"give {allowed!r}")
    seed = check_seed(seed, none=False)
    energy_tol = accuracy.energy_tolerance(energy_tol)
    refuse(model, opts["scheme"], opts["offset"])
    grid = initial_conditions if isinstance(initial_conditions, SectionGrid) else None
    if grid is not None and grid.states.size == 0:
        raise ValueError("the section grid holds no allowed point at this energy")
    X = np.asarray(initial_conditions if grid is None else grid.states, dtype=float)
    if X.ndim != 2 or X.shape[1] != model.dim or len(X) == 0:
        raise ValueError(f"initial_conditions must have shape (M, {model.dim}) (one row per "
                         f"orbit), got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError(f"initial_conditions must be finite, got a non-finite value in row "
                         f"{int(np.argmin(np.isfinite(X).all(axis=1)))}")
    m = len(X)
    chunk_size = _chunk_size(chunk_size, m, None)
    if clock is None:
        clock = compiling.Clock(f"the fli map of {model.name} by tm+log", progress)
    lh = _log_hamiltonian(model, opts["scheme"], opts["offset"])
    if h_choice is not None and "offset" in h_choice:
        # The defaults' pilot (_cheaper_steps) chose δ with h.
        lh = lh.with_offset(h_choice["offset"])
    if h is None:
        # δ (unless given) and h from the pilot: counts, never timings.
        with clock.part("pilot"):
            lh, h, h_choice = agreeing_offset(lh, X, t_end, quantile=MAP_QUANTILE,
                                              ceiling=RETRY_CEILING * energy_tol, seed=seed,
                                              every=every, retry=energy_tol)
        if h is None:
            # Not silence: the map runs, at the step of the energy pilot,
            # and says that its FLI was not checked.
            failed = h_choice
            tolerance = pilot_tolerance(INDICATORS["fli"])
            with clock.part("pilot"):
                h, h_choice = choose_h(lh, X, t_end, tolerance, quantile=MAP_QUANTILE,
                                       seed=seed)
            h_choice.update(indicator=failed, summary=(
                f"{failed['summary']} (h = {failed['tried'][0][0]:.3g} down to "
                f"{failed['tried'][-1][0]:.3g}): step chosen by the energy error to "
                f"{tolerance:g}"))
            warnings.warn(f"the FLI map of {model.name}: {h_choice['summary']} "
                          f"(h = {h:.3g}); its FLI values were not checked at h/2",
                          accuracy.AccuracyWarning, stacklevel=accuracy.user_stacklevel())
    order = np.random.default_rng(20100927).permutation(m)
    chunks = [order[i:i + chunk_size] for i in range(0, m, chunk_size)]
    done = {}
    cpu, start = time.process_time(), time.perf_counter()

    # An automatic h (the FLI rule's) is the coarse step of a retry: each
    # orbit above energy_tol runs again at h/2, h/4, … (retried); a given
    # h, or the energy rule's, is every orbit's step.
    retry = h_choice is not None and h_choice.get("rule") == "indicator"
    reference = accuracy.Reference(model, X) if retry else None
    level = np.zeros(m, dtype=np.int64)

    def run(c):
        idx = chunks[c]
        W0 = initial_deviations(model.dim, 1, len(idx), seed, idx)[:, :, 0]
        if retry:
            return retried(lh, X[idx], W0, t_end, h, energy_tol, reference.rows(idx),
                           every=every)
        return lh.outputs(X[idx], W0, t_end, h, every=every), np.zeros(len(idx), np.int64)

    def keep(c, outcome):
        done[c], level[chunks[c]] = outcome.out
        return len(chunks[c])

    with clock.part("run"), bar(progress, m, 0, "chaos_map", "orbit") as shown:
        interrupted = fan_out(None, range(len(chunks)), lambda c: _LogChunk(run(c)),
                              lambda c: (c,), keep, shown)
    values, lh_status = np.full(m, np.nan), np.zeros(m, dtype=np.int64)
    state, x_worst = np.full(X.shape, np.nan), np.full(X.shape, np.nan)
    t_reached, t_worst = np.full(m, np.nan), np.full(m, np.nan)
    counts = np.zeros(3, dtype=np.int64)
    computed = np.zeros(m, dtype=bool)
    for c, out in done.items():
        idx = chunks[c]
        values[idx], lh_status[idx] = out.fli, out.status
        state[idx], t_reached[idx] = out.x, out.t
        x_worst[idx], t_worst[idx] = out.x_worst, out.t_worst
        counts += out.counts.sum(axis=0)
        computed[idx] = True
    # The map's negative codes mean "decided": the LH's own stops (U ≤ 0,
    # budget) become failures, their reasons kept by name.
    status = np.where(lh_status < 0, int(Status.INTEGRATOR_FAILED), lh_status)
    reasons = {describe(code): int(np.sum(lh_status == code))
               for code in np.unique(lh_status[lh_status != 0]).tolist()}
    warn_failures(lh_status, "orbits", "their values are NaN")
    stops = [f"{int(np.sum(lh_status == code))}: {describe(code)}"
             for code in np.unique(lh_status[lh_status < 0]).tolist()]
    if stops:
        warnings.warn(f"{int(np.sum(lh_status < 0))} of {m} orbits were stopped by the "
                      f"logarithmic Hamiltonian ({'; '.join(stops)}); their values are NaN",
                      RuntimeWarning, stacklevel=accuracy.user_stacklevel())
    if interrupted:
        warn_interrupted("chaos map", len(done), len(chunks), "chunks", False)
    # A stopped orbit's time is where its last completed step left it.
    t_stop = np.where(computed & (status == STATUS_OK), t_end, t_reached)
    verdict, energy = _log_verdict(model, X, state, x_worst, t_worst, status, energy_tol, h)
    if h_choice is not None and "summary" in h_choice:
        verdict.notes["step"] = h_choice["summary"]
    if h_choice is not None and "offset_summary" in h_choice:
        verdict.notes["offset"] = h_choice["offset_summary"]
    if retry:
        h_choice = {**h_choice, "levels": level.tolist(),
                    "h_orbit": (h * 2.0**-level).tolist()}
        if level.any():
            verdict.notes["retried"] = (
                f"{int(np.sum(level > 0))} of {m} orbits above energy_tol = {energy_tol:g} "
                f"at h = {h:.4g} ran again at smaller steps, down to h/{2**int(level.max())} "
                "(provenance.tau_choice['h_orbit'])")
    prov = Provenance(
        kind="chaos_map", model=model.describe(), x0=[], method="tm+log",
        method_options={"time_transform": "log", "scheme": lh.scheme.describe(), "h": h,
                        "offset": lh.offset, "every": every, "backend": "cpu"},
        tau=h, t_end=t_end, seed=seed,
        options={"indicator": "fli", "threshold": None, "x0": digest(X),
                 "chunk_size": int(chunk_size), "chunks": len(chunks), "chunks_resumed": 0,
                 "client": client_label(None), "lh_failures": reasons},
        versions=package_versions(),
        counts={"lh_steps": int(counts[0]), "tail_steps": int(counts[1]),
                "gradient_evaluations": int(counts[2])},
        wall_time=time.perf_counter() - start,
        tau_choice={} if h_choice is None else dict(h_choice), code=identity.code_identity(),
        machine=identity.machine(), cpu_time=time.process_time() - cpu)
    prov.timing = {k: round(v, 6) for k, v in clock.timing.items()}
    empty = np.empty(0)
    result = ChaosMapResult(
        t=np.array([t_end]), energy_error=energy,
        state=state, provenance=prov, status=status,
        interrupted=interrupted, accuracy=verdict, indicator="fli", values=values, t_stop=t_stop,
        threshold=None, x0=X, axes=None if grid is None else list(grid.axes),
        u=empty if grid is None else grid.u, v=empty if grid is None else grid.v,
        mask=np.zeros((0, 0), dtype=bool) if grid is None else grid.mask,
        log_scale=INDICATORS["fli"].log_scale)
    accuracy.warn(verdict, "tm+log", what="the chaos map")
    return result


#: The LH steppers this process built, by model, scheme and offset: each
#: build loads a new module of the model's kernels, and the stepper's
#: kernels compile for each new one.
_LOG_HAMILTONIANS: dict = {}


def _log_hamiltonian(model, scheme, offset):
    """The :class:`~varint.time_transform.LogHamiltonian` of ``model``,
    ``scheme`` and ``offset``, built once per process (the model by its
    description, as a map's checkpoint knows it)."""
    from .time_transform import LogHamiltonian

    key = (repr(model.describe()), str(scheme), offset)
    if key not in _LOG_HAMILTONIANS:
        if len(_LOG_HAMILTONIANS) >= 8:   # a few models at a time
            _LOG_HAMILTONIANS.pop(next(iter(_LOG_HAMILTONIANS)))
        _LOG_HAMILTONIANS[key] = LogHamiltonian(model, scheme, offset=offset)
    return _LOG_HAMILTONIANS[key]


@dataclass
class _LogChunk:
    """A chunk of a logarithmic-Hamiltonian map as :func:`fan_out` takes
    it (it runs to its end: never interrupted inside)."""

    out: Any
    interrupted: bool = False


def _log_verdict(model, X, state, x_worst, t_worst, status, energy_tol, h):
    """The accuracy verdict of a logarithmic-Hamiltonian map and its final
    relative energy errors: the errors of the conserved quantities
    (:class:`varint.accuracy.Reference`, as every map measures them) at the
    final states and at each orbit's output state furthest from its initial
    energy (:class:`~varint.time_transform.LHOutputs`), the larger of the
    two the orbit's largest over its outputs; an orbit is accurate if it
    did not fail and every quantity is within ``energy_tol``. An orbit
    that was not computed (an interrupted map) has NaN errors."""
    ref = accuracy.Reference(model, X)
    with np.errstate(invalid="ignore"):
        final = ref.errors(state)
        worst = ref.errors(x_worst)
    largest = {key: np.fmax(final[key], worst[key]) for key in final}
    failed = is_failure(status)
    for errors in (final, largest):   # nothing of a failed orbit passes for a value
        for v in errors.values():
            v[failed] = np.nan
    conserved = {("energy" if key == "energy_error" else key.split(":", 1)[1]): v
                 for key, v in largest.items()}
    with np.errstate(invalid="ignore"):
        accurate = ~failed & (np.fmax.reduce(list(largest.values())) <= energy_tol)
    verdict = accuracy.Accuracy(energy_error=largest["energy_error"], conserved=conserved,
                                t_worst=np.where(failed, np.nan, t_worst),
                                energy_tol=energy_tol, accurate=accurate, tau=h)
    return accuracy.annotate(verdict, model), final["energy_error"]
