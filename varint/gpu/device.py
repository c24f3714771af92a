"""Finding a CUDA GPU, compiling for it exactly, and choosing the backend.

numba-cuda is optional (``pip install "varint[cuda]"``). Where it is
missing, or no GPU is present, ``backend="cuda"`` is refused in one line
before any work, and ``backend="auto"`` runs on the CPU. Under numba's CUDA
simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernels run as Python, thread by
thread: slow, but the same source, which is how the tests check them
without a GPU.

NVVM contracts a separate multiply and add into one fused multiply–add
unless told not to (its ``-fma=1`` default, which numba-cuda keeps). The
CPU steppers write their fused operations explicitly and round every other
product (:mod:`varint.kernels.fma`), so the kernels are compiled with
``-fma=0``: the explicit fma stay fused and nothing else is, as on the
CPU. NVVM then writes every other product and sum with an explicit
rounding (``mul.rn``, ``add.rn``), which ptxas does not fuse.

The kernels are also compiled without link-time optimisation. Where
nvJitLink is installed numba-cuda links kernels by default as LTO-IR, and
nvJitLink optimises and generates the code again with its own defaults,
``-fma=1`` among them: it contracts a·b + c into one ``fma.rn`` although
NVVM was told not to (a·b + c compiled with ``-fma=0``: ``mul.rn``,
``add.rn`` in NVVM's PTX, one ``fma.rn`` in nvJitLink's, numba-cuda 0.30.4
and CUDA 12.9). That was the cause of the 1e-11 relative difference of the H100's FLI
map from the CPU's at t = 100: the kernel's PTX read back then
(``inspect_asm``: NVVM's, before the link) had no contraction; the code
that ran was nvJitLink's. Without LTO the PTX that NVVM writes is the code
that runs, and on an H100 the Hénon–Heiles FLI, SALI and MEGNO maps equal
the CPU's bit for bit (``studies/results/bench_gpu_h100.md``; with LTO,
1e6 operands of a·b + c differ in 12 % of cases, ``studies/gpu_difference.py``).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import os
import threading
import types

from numba import njit

from ..kernels.fma import fma
from ..kernels.logarithm import py_as_bits, py_from_bits

__all__ = ["BACKENDS", "AUTO_MIN_ORBITS", "available", "simulated", "check_backend",
           "use_gpu", "kernel", "kernel_globals", "THREADS_PER_BLOCK"]

#: The values of the ``backend`` option.
BACKENDS = ("cpu", "cuda", "auto")
#: ``backend="auto"`` runs a call on the GPU from this many active orbits:
#: below, a launch and the transfers cost more than the CPU's lanes.
AUTO_MIN_ORBITS = 20000
#: Threads per block: a multiple of the warp (32); 128 leaves the scheduler
#: room to hide latency with the registers a step of Hénon–Heiles needs.
THREADS_PER_BLOCK = 128


def simulated():
    """Whether numba's CUDA simulator stands in for a GPU."""
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")


def _installed():
    return importlib.util.find_spec("numba.cuda") is not None


def available():
    """Whether CUDA kernels can run here: numba-cuda and a GPU (or the
    simulator)."""
    if simulated():
        return _installed()
    if not _installed():
        return False
    from numba import cuda

    try:
        return bool(cuda.is_available())
    except Exception:   # a broken driver is no GPU
        return False


def check_backend(backend):
    """``backend`` checked: one of :data:`BACKENDS`; "cuda" only where
    :func:`available`."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(map(repr, BACKENDS))}, "
                         f"got {backend!r}")
    if backend == "cuda" and not available():
        why = ("numba-cuda is not installed (pip install 'varint[cuda]')" if not _installed()
               else "no CUDA GPU was found")
        raise RuntimeError(f"backend='cuda': {why}; use backend='cpu' or 'auto'")
    return backend


def use_gpu(backend, n_active):
    """Whether a call with ``n_active`` orbits runs on the GPU."""
    if backend == "cuda":
        return True
    return backend == "auto" and n_active >= AUTO_MIN_ORBITS and available()


_PATCH = threading.Lock()


@contextlib.contextmanager
def _no_contraction():
    """NVVM compiles with ``-fma=0`` inside this block (see the module
    docstring); numba-cuda passes no such option itself."""
    from numba.cuda.cudadrv import nvvm

    with _PATCH:
        original = nvvm.compile_ir

        def compile_ir(llvmir, **options):
            if not options.get("fastmath"):
                options.setdefault("fma", False)
            return original(llvmir, **options)

        nvvm.compile_ir = compile_ir
        try:
            yield
        finally:
            nvvm.compile_ir = original


class _Kernel:
    """A CUDA kernel launched one thread per orbit; its first launch
    compiles it without contraction."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher

    def launch(self, n_threads, *args):
        blocks = max(1, -(-n_threads // THREADS_PER_BLOCK))
        with _no_contraction():
            self.dispatcher[blocks, THREADS_PER_BLOCK](*args)

    def ptx(self, signature, cc=(9, 0)):
        """The kernel's PTX for ``signature`` (no GPU needed)."""
        from numba import cuda

        with _no_contraction():
            return cuda.compile_ptx(self.dispatcher.py_func, signature, cc=cc)[0]


def kernel(function):
    """``function`` as a CUDA kernel (:class:`_Kernel`), linked without
    link-time optimisation (see the module docstring); the simulator has
    no linker (nor the option)."""
    from numba import cuda

    return _Kernel(cuda.jit(function) if simulated() else cuda.jit(function, lto=False))


def generated_kernel(source, prefix, entry):
    """The CUDA kernel ``entry`` of the generated Python ``source``
    (:func:`kernel`), in a module of its own named ``prefix`` + the
    source's hash, whose globals are :func:`kernel_globals`."""
    name = prefix + hashlib.sha256(source.encode()).hexdigest()[:24]
    module = types.ModuleType(name)
    module.__dict__.update(kernel_globals())
    # The source is made in this process from a model's own form: nothing
    # read from disk is run.
    exec(compile(source, f"<{name}>", "exec"), module.__dict__)
    return kernel(getattr(module, entry))


def kernel_globals():
    """The names a generated CUDA kernel uses beyond ``math`` and ``numpy``:
    numba's ``cuda`` and its types, the bit casts of its logarithm
    (:mod:`varint.kernels.logarithm`); on the simulator, a correctly rounded
    ``fma`` (the simulator's ``cuda.fma`` is a·b + c, rounded twice) and
    the bit casts in Python."""
    import numba
    from numba import cuda

    names = {"cuda": cuda, "float64": numba.float64, "int64": numba.int64}
    if simulated():
        names["fma"] = _host_fma()
        names["as_bits"], names["from_bits"] = py_as_bits, py_from_bits
    else:
        names["as_bits"], names["from_bits"] = _bit_casts()
    return names


@functools.lru_cache(maxsize=1)
def _bit_casts():
    """``as_bits``, ``from_bits`` of :mod:`varint.kernels.logarithm` as
    device functions: libdevice's bit casts."""
    from numba import cuda
    from numba.cuda import libdevice

    @cuda.jit(device=True)
    def as_bits(x):
        return libdevice.double_as_longlong(x)

    @cuda.jit(device=True)
    def from_bits(i):
        return libdevice.longlong_as_double(i)

    return as_bits, from_bits


@functools.lru_cache(maxsize=1)
def _host_fma():
    @njit
    def host_fma(a, b, c):
        return fma(a, b, c)

    return host_fma
