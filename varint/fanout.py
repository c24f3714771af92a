"""One fan-out for the workflows made of many independent runs: the chunks
of a chaos map (:mod:`varint.maps`) and the realisations of an ensemble
(:mod:`varint.ensemble`).

:func:`fan_out` runs one task per key, one after the other in this process
or as tasks on a Dask cluster taken as they finish, hands each outcome to
the workflow as it arrives (which keeps it, in its resumable store too),
advances one progress bar, and stops at Ctrl-C keeping what finished (on a
cluster it cancels the tasks left, which poll :func:`worker_threads`' check
and stop within a chunk). :func:`warn_failures` and
:func:`warn_interrupted` word what failed and what was kept the same way
for both.
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Callable, Hashable, Iterable
from typing import Any

import numpy as np

from . import _validate as check
from .accuracy import user_stacklevel
from .driver import progress_bar
from .protocol import REASONS, is_failure

__all__ = ["fan_out", "bar", "worker_threads", "cluster_threads", "client_label", "total_cpu",
           "warn_failures", "warn_interrupted"]


def fan_out(client: Any, todo: Iterable[Hashable], task: Callable[..., Any],
            arguments: Callable[[Any], tuple], keep: Callable[[Any, Any], int],
            progress: Any = None) -> bool:
    """Run ``task(*arguments(key))`` for every key of ``todo``.

    Parameters
    ----------
    client : dask.distributed.Client or None
        None: in this process, in the order of ``todo``; else as tasks on
        the cluster, kept in the order they finish.
    todo : iterable
        The keys (chunk numbers, seeds) still to compute.
    task : callable
        Picklable, for a cluster; its outcome has ``interrupted`` (Ctrl-C
        inside it: the fan-out stops without keeping it).
    arguments : callable
        ``key -> tuple`` of the task's arguments.
    keep : callable
        ``keep(key, outcome) -> n``: the workflow keeps the outcome (and
        stores it) and says how many units of the bar it was.
    progress : tqdm bar or None
        Advanced by what ``keep`` returns (:func:`bar`).

    Returns
    -------
    bool
        Whether Ctrl-C stopped it (the outcomes kept so far stay kept).
    """
    if client is None:
        try:
            for key in todo:
                outcome = task(*arguments(key))
                if outcome.interrupted:
                    return True
                _advance(progress, keep(key, outcome))
        except KeyboardInterrupt:
            return True
        return False
    from distributed import as_completed

    futures = {client.submit(task, *arguments(key), pure=False): key for key in todo}
    try:
        for future in as_completed(futures):
            _advance(progress, keep(futures[future], future.result()))
    except KeyboardInterrupt:
        client.cancel(list(futures))
        return True
    return False


def _advance(progress, n):
    if progress is not None:
        progress.update(n)


def bar(progress, total, done, desc, unit):
    """The fan-out's progress bar (:func:`varint.driver.progress_bar`) over
    ``total`` units, ``done`` of them already (resumed)."""
    return progress_bar(check.flag(progress, "progress"), done, total, desc, unit)


@contextlib.contextmanager
def worker_threads():
    """On a Dask worker, run numba on as many threads as the worker has
    (numba's setting is per calling thread), so workers sharing a machine
    do not oversubscribe it; yields the task's :func:`_cancel_check` there,
    None elsewhere."""
    # A Dask worker's process has imported distributed; any other process
    # does not import it for this check (it costs more than a second).
    distributed = sys.modules.get("distributed")
    try:
        if distributed is None:
            raise ValueError("not on a Dask worker")
        worker = distributed.get_worker()
        n = worker.state.nthreads
    except (ValueError, AttributeError):
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
    cancelled (the fan-out was interrupted): its run then stops at its next
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


def cluster_threads(client):
    """The worker threads of a Dask cluster (at least 1)."""
    info = client.scheduler_info()
    return max(1, sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))


def client_label(client):
    """How the provenance names where the tasks ran."""
    return None if client is None else f"dask ({cluster_threads(client)} threads)"


def total_cpu(times):
    """The sum of measured CPU times; None if one was not measured."""
    times = list(times)
    return None if any(t is None for t in times) else float(sum(times))


def warn_failures(status, what, consequence):
    """One warning (at the user's line) counting the failed ``what``
    ("orbits", "realisations") of ``status`` by reason; nothing if none
    failed."""
    failed = is_failure(status)
    if not failed.any():
        return
    codes = "; ".join(f"{int(n)}: {REASONS.get(int(c), f'status {int(c)}')}"
                      for c, n in zip(*np.unique(status[failed], return_counts=True),
                                      strict=True))
    warnings.warn(f"{int(failed.sum())} of {status.size} {what} failed ({codes}); "
                  f"{consequence}", RuntimeWarning, stacklevel=user_stacklevel())


def warn_interrupted(workflow, done, total, unit, kept=False):
    """One warning (at the user's line) that Ctrl-C stopped ``workflow``
    after ``done`` of ``total`` ``unit``, and whether they are kept to
    resume from."""
    warnings.warn(f"{workflow} interrupted: {done} of {total} {unit} finished"
                  + ("; they are kept in the checkpoint directory, call again to resume"
                     if kept else ""), RuntimeWarning, stacklevel=user_stacklevel())
