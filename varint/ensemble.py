"""Ensembles over disorder: one indicator for many realisations of a
disordered lattice, and its averages.

:func:`ensemble` checks its arguments once, on the first realisation's run
specification (:func:`varint.runspec.specify`, which also fixes τ for all),
and runs each realisation (one seed of the disorder each) as the
:class:`~varint.run.Run` of its own specification, in this process or as
tasks on a Dask cluster (as :func:`varint.chaos_map` runs its chunks), and
stacks the realisations' series. What the lattice laws are stated for —
⟨log₁₀ m₂⟩(t), ⟨log₁₀ Λ⟩(t) averaged over disorder (Flach, Krimer & Skokos
2009; Senyange, Many Manda & Skokos 2018) — is
:meth:`EnsembleResult.log_mean`, and the exponent of a power law with its
spread over realisations :meth:`EnsembleResult.exponent`.

Deterministic by construction: realisation s is the model built for seed s,
its initial state, and deviation vectors drawn from ``default_rng([s, 0])``;
nothing depends on the order in which realisations run, on the worker, or
on resuming.

Resuming: with ``checkpoint=DIR`` every finished realisation is written to
``DIR/seed_<s>.npz`` (:class:`varint.store.Store`: the result with the key
and parameters of its run specification,
:meth:`varint.runspec.RunSpec.parameters`) as soon as it arrives, and a
realisation in progress keeps a run checkpoint ``DIR/seed_<s>.ckpt``
(:func:`varint.run`'s, bitwise resumable). The same call again loads the finished realisations,
resumes the one in progress and runs the rest; a stored realisation whose
parameters differ from this call's is refused with a
:class:`~varint.CheckpointError` naming them, and one that is damaged or
edited (not a valid result of this ensemble's run for its seed) is reported
and run again. A full or unwritable directory costs one warning: the
ensemble goes on without keeping what it cannot write.
"""

from __future__ import annotations

import dataclasses
import io
import math
import numbers
import time
import warnings
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from . import _validate as check
from . import identity
from .checkpoint import CheckpointError, canonical, digest
from .indicators import resolve
from .accuracy import user_stacklevel
from .fanout import (bar, client_label, fan_out, total_cpu, warn_failures, warn_interrupted,
                     worker_threads)
from .results import Provenance, _Result, load_result, package_versions
from .run import Run
from .runspec import described, specify
from .store import Invalid, Store

__all__ = ["ensemble", "EnsembleResult"]

#: Fields of a single run's result that are not its series.
_NOT_SERIES = ("t", "energy_error", "state", "provenance", "status", "interrupted", "deviations")


@dataclass
class EnsembleResult(_Result):
    """Result of :func:`ensemble`.

    Attributes
    ----------
    t : ndarray, shape (n_out,)
    seeds : ndarray of int, shape (R,)
        The realisations, in the order of the call.
    values : dict of str -> ndarray, shape (R, n_out, ...)
        Every series of the indicator, stacked over realisations (NaN for
        realisations not finished or after a failure).
    energy_error : ndarray, shape (R, n_out)
    state : ndarray, shape (R, 2N)
        Final states.
    status : ndarray, shape (R,)
        0 for realisations that ran to the end, a failure code otherwise
        (−2 for one not run, after an interruption).
    wall_times : ndarray, shape (R,)
        Seconds each realisation took.
    """

    plot_kind: ClassVar[str] = "ensemble"

    seeds: np.ndarray | None = None
    values: dict | None = None
    wall_times: np.ndarray | None = None

    def __getitem__(self, name):
        try:
            return self.values[name]
        except KeyError:
            raise KeyError(f"this ensemble holds {', '.join(self.values)}; not {name!r}") from None

    def _series(self, name, column):
        v = np.asarray(self[name], dtype=float)
        if column is not None:
            v = v[..., column]
        elif v.ndim > 2:
            raise ValueError(f"{name!r} has shape {v.shape}: pick a column= (e.g. 0)")
        return v

    def log_mean(self, name, column=None):
        """⟨log₁₀|v|⟩ over the realisations at each output time.

        Parameters
        ----------
        name : str
            A series of :attr:`values` (e.g. ``"m2"``, ``"x1"``).
        column : int, optional
            Which column of a series with one (e.g. exponent 0).

        Returns
        -------
        mean, std : ndarray, shape (n_out,)
            The average of log₁₀|v| and its standard deviation over the
            realisations that have a finite value there.
        count : ndarray of int, shape (n_out,)
            How many realisations that is.
        """
        v = self._series(name, column)
        with np.errstate(divide="ignore", invalid="ignore"):
            logs = np.log10(np.abs(v))
        ok = np.isfinite(logs)
        count = ok.sum(axis=0)
        with warnings.catch_warnings(), np.errstate(invalid="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(np.where(ok, logs, np.nan), axis=0)
            std = np.nanstd(np.where(ok, logs, np.nan), axis=0)
        return mean, std, count

    def exponent(self, name, window, column=None):
        """The power law v ∝ t^a over ``window``, fitted two ways.

        Parameters
        ----------
        name : str
        window : (float, float)
            First and last time of the fit.
        column : int, optional

        Returns
        -------
        dict
            ``a``: the least-squares slope of ⟨log₁₀|v|⟩ against log₁₀ t;
            ``a_mean``, ``a_std``: mean and standard deviation of the slopes
            of the single realisations (their spread); ``a_err``: the
            standard error of that mean (a_std/√R); ``realisations``: R;
            ``window``: the output times actually used.
        """
        lo, hi = window
        t = np.asarray(self.t, dtype=float)
        use = (t >= lo * (1 - 1e-12)) & (t <= hi * (1 + 1e-12))
        if use.sum() < 3:
            raise ValueError(f"the window {window} holds {int(use.sum())} output times; a fit "
                             "needs at least 3")
        lt = np.log10(t[use])
        mean, _, _ = self.log_mean(name, column)
        a = float(np.polyfit(lt, mean[use], 1)[0]) if np.isfinite(mean[use]).all() else math.nan
        v = self._series(name, column)[:, use]
        with np.errstate(divide="ignore", invalid="ignore"):
            logs = np.log10(np.abs(v))
        slopes = np.array([np.polyfit(lt, row, 1)[0] for row in logs if np.isfinite(row).all()])
        r = slopes.size
        return {"a": a, "a_mean": float(slopes.mean()) if r else math.nan,
                "a_std": float(slopes.std(ddof=1)) if r > 1 else math.nan,
                "a_err": float(slopes.std(ddof=1) / math.sqrt(r)) if r > 1 else math.nan,
                "realisations": int(r), "window": (float(t[use][0]), float(t[use][-1]))}


#: Options of the call that go to each realisation's :class:`~varint.run.Run`
#: rather than into its specification.
_RUN_OPTIONS = ("deviations", "checkpoint_interval")


@dataclass
class _Spec:
    """What every realisation of one ensemble shares (sent to the workers):
    how to build its model and initial state from its seed, and the call's
    arguments, τ fixed once for all (:meth:`fix_step`)."""

    factory: object
    params: dict | None
    x0: object
    indicator: object
    t_end: float
    tau: float | None
    options: dict
    run_options: dict
    tau_choice: dict | None = None

    def model(self, seed):
        if self.params is not None:
            return self.factory(**self.params, seed=seed)
        return self.factory(seed)

    def initial(self, model, seed):
        return self.x0(model, seed) if callable(self.x0) else self.x0

    def specify(self, seed):
        """The :class:`~varint.runspec.RunSpec` of realisation ``seed``, its
        inputs checked (:func:`varint.runspec.specify`), with the ensemble's
        τ and output steps once :meth:`fix_step` has fixed them."""
        model = self.model(seed)
        spec = specify(model, self.initial(model, seed), self.indicator, self.t_end, self.tau,
                       seed=int(seed), **self.options)
        return spec if self.tau_choice is None else spec.with_step(self.tau, self.tau_choice)

    def fix_step(self, first):
        """Fix τ for every realisation from ``first``, the specification of
        one of them: as given, else chosen by ``first``'s pilot
        (:meth:`RunSpec.with_pilot_step`), so that all share their output
        times. Returns ``first`` with its step."""
        k, options = _vectors(first, self.run_options.get("deviations"))
        first = (first.with_step(first.tau) if first.tau is not None else
                 first.with_pilot_step(k=k, accumulator=first.indicator.accumulator_for(options)))
        self.tau, self.tau_choice = first.tau, first.tau_choice
        return first

    def job(self, seed, checkpoint=None):
        """The prepared run of realisation ``seed``."""
        return Run(self.specify(seed), progress=False, errors="flag", checkpoint=checkpoint,
                   **self.run_options)


def _vectors(spec, deviations):
    """(k, the indicator's options with k): how many deviation vectors each
    realisation of ``spec`` carries (given, or the indicator's choice)."""
    ind, options = spec.indicator, dict(spec.options)
    k = (ind.vectors(spec.model, options, None) if deviations is None
         else np.shape(deviations)[-1])
    if ind.count_option is not None:
        options[ind.count_option] = k
    return k, options


@dataclass
class _Realisation:
    """One realisation's outcome: its result, the parameters that determine
    it, and why its run checkpoint could not be kept (or None)."""

    result: _Result
    parameters: dict
    note: str | None

    @property
    def interrupted(self):
        return self.result.interrupted


def _realise(spec, seed, checkpoint):
    """One realisation, run to the end (or interrupted)."""
    with worker_threads(), warnings.catch_warnings():
        # Failures are counted by the ensemble, which warns once.
        warnings.simplefilter("ignore", RuntimeWarning)
        note = None
        try:
            job = spec.job(seed, checkpoint)
            result = job.execute()
        except CheckpointError as exc:
            # A full or unwritable directory costs the checkpoint, not the
            # realisation (a damaged checkpoint is still refused).
            if checkpoint is None or not isinstance(exc.__cause__, OSError):
                raise
            note = str(exc)
            job = spec.job(seed)
            result = job.execute()
    return _Realisation(result, _parameters(job.spec, spec.run_options), note)


def _parameters(run_spec, run_options):
    """What determines a realisation's result (the key of its stored piece):
    its specification's parameters (:meth:`RunSpec.parameters`), and the
    digest of the deviation vectors when the call gave them."""
    parameters = run_spec.parameters()
    deviations = run_options.get("deviations")
    parameters["deviations"] = None if deviations is None else digest(
        np.asarray(deviations, dtype=float))
    return canonical(parameters)


def _name(seed):
    return f"seed_{int(seed)}"


def _load_realisation(store, seed, expected, first):
    """The stored result of realisation ``seed`` if it is there, of these
    ``expected`` run parameters and valid (:func:`_checked_realisation`);
    None if not there (a damaged one is reported and recomputed).

    Raises
    ------
    CheckpointError
        If it belongs to an ensemble with other parameters (naming them).
    """
    piece = store.load(_name(seed), expected, foreign="refuse")
    if piece is None:
        return None
    try:
        return _checked_realisation(piece, seed, first)
    except (Invalid, ValueError) as exc:
        store.discard(store.file(_name(seed)), exc)
        return None


def _checked_realisation(piece, seed, first):
    """The result a stored piece holds, after checking that it is what the
    run ``first`` (of this ensemble) makes for ``seed``: a valid result
    (:func:`varint.results.load_result`) of the indicator's class, finished,
    of this seed, at these output times, with one state of this model."""
    if set(piece.arrays) != {"result"} or piece.arrays["result"].dtype != np.uint8:
        raise Invalid("it holds no result")
    result = load_result(io.BytesIO(piece.arrays["result"].tobytes()))
    t = first.steps * first.tau
    if type(result) is not first.indicator.result:
        raise Invalid(f"it holds a {type(result).__name__}, not a "
                      f"{first.indicator.result.__name__}")
    if result.interrupted or result.provenance.seed != seed:
        raise Invalid("it holds an unfinished run, or another seed's")
    if result.t.shape != t.shape or not np.array_equal(result.t, t):
        raise Invalid("its output times are not this ensemble's")
    if np.shape(result.state) != (first.model.dim,) or np.ndim(result.status) != 0:
        raise Invalid(f"its state has shape {np.shape(result.state)}, not "
                      f"({first.model.dim},)")
    return result


class _Store(Store):
    """The checkpoint directory of an ensemble (see the module docstring)."""

    def __init__(self, path):
        super().__init__(path, "ensemble")

    def run_checkpoint(self, seed):
        return self.path / f"{_name(seed)}.ckpt"

    def keep(self, seed, result, parameters):
        buf = io.BytesIO()
        result.save(buf)
        if self.save(_name(seed), {"result": np.frombuffer(buf.getvalue(), dtype=np.uint8)},
                     {}, parameters):
            self.run_checkpoint(seed).unlink(missing_ok=True)


def _seeds(seeds):
    try:
        values = list(seeds)
    except TypeError:
        raise ValueError(f"seeds must be a sequence of non-negative integers, got {seeds!r}") \
            from None
    if not values:
        raise ValueError("seeds holds no realisation")
    for s in values:
        if isinstance(s, (bool, np.bool_)) or not isinstance(s, numbers.Integral) or s < 0:
            raise ValueError(f"seeds must be non-negative integers, got {s!r}")
    if len(set(int(s) for s in values)) != len(values):
        raise ValueError("seeds must be distinct (each seed is one realisation)")
    return [int(s) for s in values]


def ensemble(model, seeds, x0, indicator, t_end, tau=None, *, params=None, client=None,
             checkpoint=None, progress=None, **options):
    """An indicator over many realisations of a disordered model.

    Parameters
    ----------
    model : type or callable
        A model class taking ``seed=`` (e.g. :class:`varint.models.DDNLS`),
        built as ``model(**params, seed=s)``; or a function ``seed -> Model``.
    seeds : sequence of int
        One realisation per seed (distinct, non-negative).
    x0 : array_like, shape (2N,), or callable
        The initial state of every realisation, or ``x0(model, seed) ->
        state`` (e.g. ``lambda m, s: m.initial_block(21, 0.1, seed=s)``).
    indicator : str or Indicator
        As for :func:`varint.run` (``"dvd"``, ``"spreading"``, ``"x1"``, …).
    t_end, tau : float
        As for :func:`varint.run`; a τ left open is chosen once, by the
        pilot of the first realisation (``provenance.tau_choice``), and
        every realisation runs it, so that all share their output times.
    params : dict, optional
        The model's parameters when ``model`` is a class.
    client : dask.distributed.Client, optional
        Run the realisations as tasks on this cluster (each worker needs
        varint); values are bitwise those of a run here.
    checkpoint : str or os.PathLike, optional
        Directory that keeps the finished realisations (module docstring).
    progress : bool, optional
        A progress bar over realisations (by default when stderr is a
        terminal).
    **options
        Everything else :func:`varint.run` takes (``scheme``, ``t_out``,
        ``method``, the indicator's options, …) except ``seed``, which is
        each realisation's.

    Returns
    -------
    EnsembleResult
        The stacked series, with :meth:`~EnsembleResult.log_mean` and
        :meth:`~EnsembleResult.exponent`. After Ctrl-C: the realisations
        finished so far, ``interrupted=True``.

    Examples
    --------
    Two realisations of a short DDNLS chain (a real study takes 50–100
    realisations of 512 sites to t = 1e5 and beyond, with ``checkpoint=``):

    >>> import varint
    >>> r = varint.ensemble(varint.models.DDNLS, range(2),
    ...                     lambda m, s: m.initial_block(3, 1.0, seed=s), "dvd", 10.0,
    ...                     tau=0.1, params={"shape": 32, "W": 4, "beta": 0.04},
    ...                     scheme="s9ABC6", progress=False)
    >>> sorted(r.values)[:3]
    ['centre', 'dvd_m2', 'dvd_participation']
    >>> r.exponent("x1", (1.0, 10.0))["realisations"]
    2
    """
    start = time.perf_counter()
    if "seed" in options:
        raise ValueError("seed= is each realisation's own seed; give the realisations as seeds")
    if not callable(model):
        raise ValueError(f"model must be a model class or a function seed -> Model, got "
                         f"{type(model).__name__} {model!r}")
    if params is not None and not isinstance(params, dict):
        raise ValueError(f"params must be a dict of the model's parameters, got {params!r}")
    if isinstance(model, type) and params is None:
        params = {}
    seeds = _seeds(seeds)
    check.dask_client(client)
    if not callable(x0):
        x0 = check.real_array(x0, "x0")
    run_options = {k: options.pop(k) for k in _RUN_OPTIONS if k in options}
    spec = _Spec(model, params, x0, resolve(indicator)[0], t_end, tau, options, run_options)
    # Every input checked before any long run, on the first realisation's
    # specification, whose pilot (if any) fixes τ for all.
    first = spec.fix_step(spec.specify(seeds[0]))
    store = None if checkpoint is None else _Store(checkpoint)
    results, parameters = {}, {}
    if store is not None:
        for s in seeds:
            own = first if s == seeds[0] else spec.specify(s)
            expected = _parameters(own, run_options)
            found = _load_realisation(store, s, expected, own)
            if found is not None:
                results[s], parameters[s] = found, expected
    resumed = len(results)
    todo = [s for s in seeds if s not in results]

    def arguments(s):
        ckpt = None if store is None or store.unwritable else str(store.run_checkpoint(s))
        return spec, s, ckpt

    def keep(s, outcome):
        results[s], parameters[s] = outcome.result, outcome.parameters
        if outcome.note is not None:
            warnings.warn(f"{outcome.note}; realisation {s} was run without a checkpoint",
                          RuntimeWarning, stacklevel=user_stacklevel())
        if store is not None:
            store.keep(s, outcome.result, outcome.parameters)
        return 1

    with bar(progress, len(seeds), resumed, "ensemble", "realisation") as shown:
        interrupted = fan_out(client, todo, _realise, arguments, keep, shown)
    return _assemble(first, _vectors(first, run_options.get("deviations"))[1], seeds, results,
                     resumed, interrupted, store is not None, client, time.perf_counter() - start)


def _series(result):
    """The series of one realisation's result by name."""
    out = {}
    for f in dataclasses.fields(result):
        if f.name in _NOT_SERIES:
            continue
        value = getattr(result, f.name)
        if isinstance(value, dict):
            prefix = "" if f.name == "values" else f"{f.name}_"
            out.update({f"{prefix}{k}": np.asarray(v) for k, v in value.items()})
        elif isinstance(value, np.ndarray):
            out[f.name] = value
    return out


def _assemble(first, ind_options, seeds, results, resumed, interrupted, kept, client, wall):
    """The :class:`EnsembleResult` of the realisations finished (``results``
    by seed), ``first`` the specification of the first, ``ind_options`` its
    indicator's options."""
    r_count, dim = len(seeds), first.model.dim
    t = first.steps * first.tau
    n_out = t.size
    status = np.full(r_count, -2, dtype=np.int64)
    energy = np.full((r_count, n_out), np.nan)
    state = np.full((r_count, dim), np.nan)
    walls = np.full(r_count, np.nan)
    values, counts = {}, {}
    for i, s in enumerate(seeds):
        res = results.get(s)
        if res is None:
            continue
        status[i] = int(res.status)
        energy[i] = res.energy_error
        state[i] = res.state
        walls[i] = res.provenance.wall_time
        for key, n in res.provenance.counts.items():
            counts[key] = counts.get(key, 0) + int(n)
        for name, arr in _series(res).items():
            if name not in values:
                values[name] = np.full((r_count,) + arr.shape, np.nan)
            values[name][i] = arr
    warn_failures(status, "realisations", "their later values are NaN")
    if interrupted:
        warn_interrupted("ensemble", len(results), r_count, "realisations", kept)
    some = next(iter(results.values()), None)
    p = some.provenance if some is not None else None
    options = {"indicator": first.indicator.name, "seeds": seeds, "realisations": r_count,
               "finished": len(results), "resumed": resumed, "options": canonical(ind_options),
               "client": client_label(client)}
    model = dict(first.model.describe())
    model.pop("seed", None)
    prov = Provenance(kind="ensemble", model=model, x0=[], method=first.method,
                      method_options=(p.method_options if p is not None
                                      else described(first.method_options)),
                      tau=first.tau, t_end=first.t_end, seed=None, options=options,
                      tau_choice=dict(first.tau_choice),
                      versions=p.versions if p is not None else package_versions(),
                      counts=counts, wall_time=wall,
                      code=p.code if p is not None else identity.code_identity(),
                      machine=p.machine if p is not None else identity.machine(),
                      cpu_time=total_cpu(r.provenance.cpu_time for r in results.values()))
    return EnsembleResult(t=t, energy_error=energy, state=state, provenance=prov, status=status,
                          interrupted=interrupted, seeds=np.array(seeds, dtype=np.int64),
                          values=values, wall_times=walls)
