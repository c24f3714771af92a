"""Compiled kernels: array-in, array-out numba functions behind the methods.

* :mod:`~varint.kernels.banded` — symmetric band matrices, the storage of
  every Hessian.
* :mod:`~varint.kernels.checks` — the end-of-interval checks and the
  renormalisation every stepper shares.
* :mod:`~varint.kernels.tm` — the generic tangent-map stepper.

Nothing here validates input: the API does, before a kernel is called.
"""
