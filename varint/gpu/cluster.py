"""Several GPUs of one machine through Dask: one worker per GPU.

A chaos map on a Dask client sends its chunks to the workers as tasks
(:mod:`varint.fanout`); each chunk is a run of its own, seeded by its
orbits' indices, so the map's values do not depend on which worker ran
which chunk, nor on the chunk size (bitwise). To run on every GPU of a
machine, each worker must see one GPU: :func:`local_gpu_cluster` starts one
worker process per GPU with ``CUDA_VISIBLE_DEVICES`` set to it (before CUDA
is initialised there) and one thread, so that its chunks run one after the
other on its GPU::

    from distributed import Client
    from varint.gpu.cluster import local_gpu_cluster

    with local_gpu_cluster() as cluster, Client(cluster) as client:
        r = varint.chaos_map(model, grid, "fli", t_end=1e3, backend="cuda",
                             client=client)

Several machines: start one ``dask worker --nthreads 1`` per GPU with its
``CUDA_VISIBLE_DEVICES`` and give ``chaos_map`` a client of that scheduler.
Give a map at least as many chunks as GPUs (``chunk_size``), and chunks
large enough to fill a GPU (1e5 orbits or more).
"""

from __future__ import annotations

import os

from . import device

__all__ = ["local_gpu_cluster", "gpu_count"]


def gpu_count():
    """The CUDA GPUs of this machine (those ``CUDA_VISIBLE_DEVICES``
    leaves visible); 0 without numba-cuda or a driver. On numba's CUDA
    simulator, its one simulated device."""
    if not device.available():
        return 0
    from numba import cuda

    return len(cuda.gpus)


def local_gpu_cluster(devices=None, **scheduler_options):
    """A Dask cluster on this machine with one worker process per GPU.

    Parameters
    ----------
    devices : int or sequence of int, optional
        The GPUs to use: their number (the first ones) or their indices
        (as ``CUDA_VISIBLE_DEVICES`` counts them); every GPU by default.
    **scheduler_options
        Passed to the scheduler (e.g. ``dashboard_address=":8787"``; by
        default no dashboard).

    Returns
    -------
    distributed.SpecCluster
        Use as a context manager, and give ``distributed.Client(cluster)``
        to :func:`varint.chaos_map` with ``backend="cuda"``.

    Raises
    ------
    RuntimeError
        Where no GPU is found (:func:`gpu_count`).
    ValueError
        For a device that is not one of this machine's GPUs.
    """
    from distributed import Nanny, Scheduler, SpecCluster

    n = gpu_count()
    if n == 0:
        raise RuntimeError("local_gpu_cluster: no CUDA GPU was found (numba-cuda and a driver "
                           "are needed); use a CPU cluster, distributed.LocalCluster()")
    if devices is None:
        devices = list(range(n))
    elif isinstance(devices, int):
        devices = list(range(devices))
    else:
        devices = [int(i) for i in devices]
    # The simulator's one device stands in for any number of them.
    top = float("inf") if device.simulated() else n
    if not devices or len(set(devices)) != len(devices) or not all(
            0 <= i < top for i in devices):
        raise ValueError(f"devices must be distinct GPUs among the {n} of this machine "
                         f"(0..{n - 1}), got {devices!r}")
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    ids = visible.split(",") if visible else [str(i) for i in range(max(devices) + 1)]
    workers = {f"gpu-{i}": {"cls": Nanny, "options": {
        "nthreads": 1, "env": {"CUDA_VISIBLE_DEVICES": ids[i] if i < len(ids) else str(i)}}}
        for i in devices}
    scheduler_options.setdefault("dashboard_address", None)
    return SpecCluster(workers=workers,
                       scheduler={"cls": Scheduler, "options": scheduler_options})
