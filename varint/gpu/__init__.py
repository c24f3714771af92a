"""Chaos maps and batches on a CUDA GPU (``backend="cuda"``).

* :mod:`~varint.gpu.emit` — the generated tangent-map stepper, emitted for
  one orbit per CUDA thread;
* :mod:`~varint.gpu.device` — finding a GPU, exact compilation, choosing
  the backend;
* :mod:`~varint.gpu.advance` — a call of the TM propagator on the GPU;
* :mod:`~varint.gpu.resident` — the orbits' state kept on the device
  between calls;
* :mod:`~varint.gpu.energy` — the snapshots' energies, computed on the
  device (the accuracy verdict's input);
* :mod:`~varint.gpu.cluster` — one Dask worker per GPU.
"""
