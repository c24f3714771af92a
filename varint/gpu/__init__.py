"""Chaos maps and batches on a CUDA GPU (``backend="cuda"``).

* :mod:`~varint.gpu.emit` — the generated tangent-map stepper, emitted for
  one orbit per CUDA thread;
* :mod:`~varint.gpu.device` — finding a GPU, exact compilation, choosing
  the backend;
* :mod:`~varint.gpu.advance` — a call of the TM propagator on the GPU.
"""
