"""Input checks shared by the public API: each names the bad value and what
was expected, before anything reaches a compiled kernel."""

from __future__ import annotations

import errno
import numbers
import os
import tempfile
import threading
from pathlib import Path

import numpy as np

from .files import is_device_path
from .kernels.resolved import Resolved


def positive_float(value, name):
    """``value`` as a float that is finite and > 0."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return value


def horizon(t_end, tau):
    """``(t_end, tau)`` checked: both finite, τ > 0, t_end ≥ τ, and at most
    :data:`MAX_STEPS` steps."""
    tau = positive_float(tau, "tau")
    if isinstance(t_end, bool) or not isinstance(t_end, numbers.Real) or not np.isfinite(t_end):
        raise ValueError(f"t_end must be a finite number, got {t_end!r}")
    t_end = float(t_end)
    if t_end < 0:
        raise ValueError(f"t_end must be >= 0, got {t_end!r}")
    if t_end < tau * (1 - 1e-12):
        raise ValueError(f"t_end = {t_end!r} is shorter than one step tau = {tau!r}")
    step_count(t_end, tau)
    return t_end, tau


def end_time(t_end, name="t_end"):
    """``t_end`` as a float that is finite and > 0 (before τ is known)."""
    if isinstance(t_end, bool) or not isinstance(t_end, numbers.Real) or not np.isfinite(t_end):
        raise ValueError(f"{name} must be a finite number, got {t_end!r}")
    if t_end < 0:
        raise ValueError(f"{name} must be >= 0, got {t_end!r}")
    if t_end == 0:
        raise ValueError(f"{name} must be > 0 (a run takes at least one step), got {t_end!r}")
    return float(t_end)


def real_array(value, name):
    """``value`` as a new float64 array.

    NumPy would silently drop imaginary parts, turn ``None`` into NaN and
    parse strings; here complex, boolean, text and non-numeric entries are
    refused, naming ``name``.
    """
    try:
        a = np.asarray(value)
    except ValueError as exc:  # ragged nested sequences
        raise ValueError(f"{name} must be a rectangular array of real numbers, got {value!r}"
                         ) from exc
    kind = a.dtype.kind
    if kind == "O":  # e.g. SymPy numbers, Decimals, or a None among floats
        for v in a.flat:
            if not _real_number(v):
                raise ValueError(f"{name} must hold real numbers, got {v!r} "
                                 f"({type(v).__name__})")
        kind = "f"
    if kind == "c":
        raise ValueError(f"{name} must be real, got complex values (dtype {a.dtype})")
    if kind not in "iuf":
        raise ValueError(f"{name} must be an array of real numbers, got dtype {a.dtype} "
                         f"({value!r})")
    # A broadcast view or a memory map may stand for more numbers than fit.
    check_memory(array_bytes(a.shape), f"{name} of shape {a.shape} (as float64)")
    return np.array(a, dtype=np.float64)


def _real_number(v):
    if isinstance(v, (bool, np.bool_, str, bytes, complex, np.complexfloating)):
        return False
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True


def flag(value, name):
    """``value`` if it is True, False or None."""
    if value is not None and not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True, False or None, got {value!r}")
    return None if value is None else bool(value)


def output_times(t_out, name="t_out", t_end=None):
    """``t_out`` as None, a positive integer count, or a 1-D float array of
    increasing finite times, in (0, t_end] if ``t_end`` is given (see
    :func:`varint.state.output_steps` for their meaning)."""
    if t_out is None:
        return None
    if isinstance(t_out, np.ndarray) and t_out.ndim == 0:
        t_out = t_out.item()
    if np.isscalar(t_out):
        if (isinstance(t_out, (bool, np.bool_)) or not isinstance(t_out, numbers.Real)
                or not float(t_out).is_integer() or t_out < 1):
            raise ValueError(f"{name} as a count must be a positive integer, got {t_out!r}")
        return int(t_out)
    t = real_array(t_out, name)
    if t.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array of times, got shape {t.shape}")
    if t.size == 0 or not np.isfinite(t).all():
        raise ValueError(f"{name} must be a non-empty array of finite times")
    if t.size > 1 and (np.diff(t) <= 0).any():
        raise ValueError(f"{name} must be strictly increasing")
    if t_end is not None and not (t[0] > 0 and t[-1] <= t_end * (1 + 1e-12)):
        raise ValueError(f"{name} must lie in [tau, t_end] = (0, {t_end!r}], got "
                         f"{float(t[0])!r}..{float(t[-1])!r}")
    return t


def states(model, x0, name="x0"):
    """Initial states as a float64 array of shape (M, 2N), and whether the
    caller passed a single state (so results are squeezed)."""
    dim = model.dim
    if (type(x0) is np.ndarray and x0.dtype == np.float64 and x0.shape == (dim,)
            and np.count_nonzero(np.isfinite(x0)) == dim):
        # The common case (a prepared run's call), the same new array as
        # below in two NumPy calls. (count_nonzero, not all(): a reduction
        # costs ~1.5 µs more on a few numbers.)
        return x0[None].copy(), True
    x = real_array(x0, name)
    single = x.ndim == 1
    if single:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != dim:
        raise ValueError(
            f"{name} must have shape ({dim},) or (M, {dim}) for {model.name} (q and p of "
            f"{model.n_dof} degrees of freedom), got shape {np.shape(x0)}")
    if x.shape[0] == 0:
        raise ValueError(f"{name} holds no orbit (shape {np.shape(x0)})")
    bad = ~np.isfinite(x)
    if bad.any():
        m, i = np.argwhere(bad)[0]
        where = f"component {i}" if single else f"orbit {m}, component {i}"
        raise ValueError(f"{name} must be finite; {where} is {float(x[m, i])!r}")
    return np.ascontiguousarray(x), single


def n_vectors(k, dim, name="k", minimum=1):
    """Number of deviation vectors, an integer in minimum..2N."""
    if isinstance(k, bool) or not isinstance(k, numbers.Integral):
        raise ValueError(f"{name} must be an integer in {minimum}..{dim}, got {k!r}")
    k = int(k)
    if not (minimum <= k <= dim):
        raise ValueError(f"{name} must be in {minimum}..{dim} (2N for this model), got {k}")
    return k


def deviations(W, dim, m_orbits, name="deviations"):
    """Given deviation vectors as a float64 array (M, 2N, k).

    Accepts (2N,), (2N, k) (shared by all orbits) or (M, 2N, k).
    """
    W = real_array(W, name)
    if W.ndim == 1:
        W = W[:, None]
    if W.ndim == 2:
        W = np.broadcast_to(W, (m_orbits,) + W.shape)
    if W.ndim != 3 or W.shape[0] != m_orbits or W.shape[1] != dim:
        raise ValueError(
            f"{name} must have shape ({dim}, k) or ({m_orbits}, {dim}, k) (one column per "
            f"vector), got shape {W.shape}")
    if not np.isfinite(W).all():
        raise ValueError(f"{name} must be finite; it contains NaN or inf")
    return np.ascontiguousarray(W)


#: The range of the largest entry of a one-column block in which
#: :func:`full_rank` skips the length: it is at most √2N times that entry,
#: finite for any 2N below 10¹⁶.
_TINY, _ONE_COLUMN_MAX = np.finfo(float).tiny, 1e300


def steps_arguments(model, x, W, tau):
    """The arguments of n steps of a map from one state
    (:func:`varint.methods.tm.tangent_map_steps`,
    :func:`varint.methods.parts.parts_steps`): ``x`` as a new float64 array
    of shape (1, 2N) and ``W`` as one of shape (2N, k) (None: k = 0), once
    ``x`` is finite and of the model's length and ``tau`` finite and
    non-zero."""
    x = np.array(x, dtype=np.float64).reshape(1, -1)
    if x.shape[1] != model.dim or not np.isfinite(x).all():
        raise ValueError(f"x must be a finite state of length {model.dim}")
    if not (np.isfinite(tau) and tau != 0):
        raise ValueError(f"tau must be finite and non-zero, got {tau!r}")
    W = np.zeros((model.dim, 0)) if W is None else np.array(W, dtype=np.float64)
    return x, W.reshape(model.dim, -1)


def full_rank(W, name="deviations"):
    """Raise if the k columns of any (2N, k) block are linearly dependent."""
    if W.shape[2] == 0:
        return
    if W.shape[2] == 1:
        # One column's singular value is its length (a chaos map's FLI
        # vectors: no SVD of 10⁵ matrices), scaled as LAPACK scales it so
        # that a subnormal column's squares do not underflow.
        # The largest entry of each column, component by component (a
        # reduction along a row of 2N numbers is ~3x slower in NumPy).
        entries = np.abs(W[:, :, 0])
        big = entries[:, 0].copy()
        for i in range(1, entries.shape[1]):
            np.maximum(big, entries[:, i], out=big)   # NaN propagates, as in max()
        if ((big >= _TINY) & (big <= _ONE_COLUMN_MAX)).all():
            # Then the column scaled by its largest entry has that entry 1
            # and length in [1, √2N]: s is finite and at least the smallest
            # normal number, so the ratio below is s / s = 1 for every
            # orbit, which passes (one pass over the vectors instead of
            # five).
            return
        unit = np.divide(W[:, :, 0], big[:, None], out=np.zeros(W.shape[:2]),
                         where=big[:, None] > 0)
        s = (big * np.linalg.norm(unit, axis=1))[:, None]
    else:
        s = np.linalg.svd(W, compute_uv=False)
    rel = s[:, -1] / np.maximum(s[:, 0], _TINY)
    bad = np.flatnonzero(~(rel > 1e-12))
    if bad.size:
        raise ValueError(
            f"{name} of orbit {bad[0]} are linearly dependent (smallest/largest singular value "
            f"{rel[bad[0]]:.3g}); expected k independent vectors")


def orthonormal(W, name="deviations", tol=1e-10):
    """Raise unless every (2N, k) block has orthonormal columns."""
    k = W.shape[2]
    if k == 0:
        return
    err = np.abs(np.matmul(W.transpose(0, 2, 1), W) - np.eye(k)).max(axis=(1, 2))
    bad = np.flatnonzero(~(err <= tol))
    if bad.size:
        # Dependent vectors are the more telling message (and orthonormal
        # ones are independent, so the SVD is needed only here).
        full_rank(W, name)
        raise ValueError(
            f"{name} of orbit {bad[0]} are not orthonormal (max |WᵀW − I| = {err[bad[0]]:.3g}); "
            "the Lyapunov spectrum needs orthonormal initial vectors: orthonormalise them "
            "(e.g. numpy.linalg.qr) or let seed= draw them")


def choice(value, options, name):
    """``value`` if it is one of ``options`` (case-insensitive for strings)."""
    key = value.lower() if isinstance(value, str) else value
    if key not in options:
        raise ValueError(f"unknown {name} {value!r}; expected one of: {', '.join(map(str, options))}")
    return key


# -- sizes against the memory of the machine -----------------------------------
def available_memory():
    """Bytes that new allocations can use, or None if unknown.

    ``MemAvailable`` of ``/proc/meminfo`` (free memory plus caches the kernel
    can drop), else the free physical pages (``os.sysconf``); lowered to what
    a cgroup memory limit (containers, batch jobs) still allows.
    """
    free = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    free = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if free is None:
        try:
            free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (AttributeError, ValueError, OSError):
            return None
    limit = _cgroup_headroom()
    return free if limit is None else min(free, limit)


def _cgroup_headroom():
    """Limit minus usage of this process's cgroup (v2, else v1), or None."""
    for limit_file, usage_file in (("memory.max", "memory.current"),
                                   ("memory.limit_in_bytes", "memory.usage_in_bytes")):
        for folder in ("/sys/fs/cgroup", "/sys/fs/cgroup/memory"):
            try:
                with open(os.path.join(folder, limit_file)) as f:
                    limit = f.read().strip()
                with open(os.path.join(folder, usage_file)) as f:
                    usage = int(f.read().strip())
            except (OSError, ValueError):
                continue
            # "max" (v2) or a huge number (v1) mean no limit.
            if limit.isdigit() and int(limit) < 2 ** 60:
                return max(0, int(limit) - usage)
            return None
    return None


def array_bytes(*shapes, itemsize=8):
    """Bytes of arrays of these shapes (exact Python integers: no overflow)."""
    total = 0
    for shape in shapes:
        n = 1
        for d in (shape if isinstance(shape, (tuple, list)) else (shape,)):
            n *= int(d)
        total += n
    return total * itemsize


def format_bytes(n):
    """``n`` bytes as a short text, e.g. ``"7.3 TiB"``."""
    value = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if value < 1024 or unit == "PiB":
            return f"{value:.3g} {unit}" if unit != "B" else f"{int(value)} B"
        value /= 1024
    return f"{value:.3g} PiB"


#: Requests smaller than this are not checked: they cannot be what exhausts
#: the memory, and reading it costs ~0.1 ms (a chaos map checks dozens).
_UNCHECKED_BYTES = 2 ** 24


def check_memory(nbytes, what):
    """Refuse work whose arrays would not fit in the available memory.

    Call it with an estimate of the bytes a computation will allocate
    before allocating any of them, so an absurd size fails at once with the
    size named instead of swapping the machine or failing deep inside NumPy.

    Parameters
    ----------
    nbytes : int
        Bytes needed (:func:`array_bytes` helps).
    what : str
        The computation and the size that decides it, for the message, e.g.
        ``"FPUBeta(n=1000000000000)"``.

    Raises
    ------
    ValueError
        ``"<what> needs about 7.3 TiB of memory, but 21.4 GiB is available"``.
        Nothing is raised when the available memory is unknown, nor for
        fewer than 16 MiB.
    """
    if nbytes < _UNCHECKED_BYTES:
        return
    free = available_memory()
    if free is not None and nbytes > free:
        raise ValueError(f"{what} needs about {format_bytes(nbytes)} of memory, but "
                         f"{format_bytes(free)} is available")


#: Most steps (t_end / tau) a run may take: the step counter is an int64
#: and outputs are stored at step indices.
MAX_STEPS = 2 ** 62


def step_count(t_end, tau, limit=MAX_STEPS):
    """``round(t_end / tau)``, refused above ``limit`` (e.g. ``tau=1e-300``
    or ``t_end=1e300``, which would overflow the step counter or run for
    ever); call after :func:`horizon`."""
    n = t_end / tau
    if not n <= limit:
        raise ValueError(f"t_end / tau = {t_end:g} / {tau:g} = {n:.3g} steps, more than the "
                         f"{limit:.3g} a run can take; use a larger tau or a shorter t_end")
    return max(1, round(n))


#: Kernel evaluations of one block of :func:`kernels` hold at most this many
#: numbers.
_KERNEL_BLOCK = 2 ** 18
#: At most this many states are evaluated from Python by :func:`kernels`
#: (~2.5 µs a state), more by the compiled pass (~80 µs a call + ~0.3 µs a
#: state).
_PYTHON_STATES = 16


def checked_kernels(model):
    """The kernels (∇V, D²V, third derivatives) :func:`kernels` evaluates:
    the model's ``checked_kernels`` where it names them (a model whose
    singular states one of its kernels already shows, e.g.
    :attr:`varint.models.Planetary.checked_kernels`), else its own three."""
    return getattr(model, "checked_kernels", None) or (model.grad_kernel, model.hess_kernel,
                                                       model.third_kernel)


def kernels(model, X, what="the initial state"):
    """Evaluate the model's derivative kernels (∇V, D²V, the third
    derivatives) at every state of ``X`` (M, 2N) before any long work, and
    refuse a state where one is not finite.

    A potential singular somewhere (1/r, log r, √r) is a legitimate model;
    an orbit that *starts* on its singularity is a bad argument, not a run
    that fails at its first step. An orbit that later runs into it fails
    with :class:`~varint.IntegrationError` (``Status.*_NONFINITE``).

    Up to :data:`_PYTHON_STATES` states are evaluated from Python; more in
    one compiled pass
    (:func:`varint.kernels.finite.first_nonfinite`, ~0.3 µs a state) that
    stops at the first where a kernel is not finite; that state is then
    evaluated from Python, which names what is wrong. Kernels that the pass
    cannot call (not numba functions of the protocol's types, or one that
    raises) are evaluated from Python at every state (~2.5 µs a state).

    Raises
    ------
    ValueError
        Naming the state (``what``, and the orbit of a batch), q and the
        kernel that is not finite there.
    TypeError
        If the kernels cannot be compiled or called as the protocol says
        (:mod:`varint.models.base`).
    """
    X = np.asarray(X, dtype=float)
    q_all = np.ascontiguousarray(X[:, :model.n_dof])
    if len(q_all) <= _PYTHON_STATES:
        # A few states: the compiled pass's fixed cost (numba converts each
        # kernel to a first-class function at every call, ~80 µs) is more
        # than evaluating them from Python.
        if _finite_from_source(model, q_all):
            return
        _evaluate(model, q_all, np.arange(len(q_all)), what, len(X))
        return
    first = _scan(model, q_all)
    if first is None:
        _evaluate(model, q_all, np.arange(len(q_all)), what, len(X))
    elif first >= 0:
        _evaluate(model, q_all, np.array([first]), what, len(X))


class KernelCheck:
    """:func:`kernels` for the calls of one prepared run: the buffers and
    set-up of one state's evaluation made once (a prepared run's call
    checks its states every time).

    One state is evaluated into the kept buffers and only tested finite;
    where a kernel raises or is not finite there, or for several states,
    :func:`kernels` does the whole check, which names what is wrong (the
    same message as a one-shot call's).
    """

    def __init__(self, model):
        self.model = model
        # Buffers per thread (a prepared run called from several threads
        # must not test one thread's values for another's state), made at
        # a thread's first check (a map has none).
        self._local = threading.local()
        # The kernels called through their compiled versions, looked up
        # once (:class:`~varint.kernels.resolved.Resolved`), made at the
        # first check (a map has none): q and the buffers are made here,
        # the same way at every call, and the parameters are the model's
        # array of that first check.
        self._params = self._resolved = None
        #: Whether all three of :attr:`_resolved` are compiled (then
        #: :meth:`states` may evaluate them before the state is known
        #: finite).
        self._compiled = False
        # (A model's kernels are numba's: numba is loaded already.)
        from .finite_values import ALL_FINITE

        #: The compiled test of the kept values (:meth:`states`).
        self._all_finite = ALL_FINITE

    def _made(self):
        """(the state, its q, all values, ∇V, D²V, third derivatives, v):
        the state (its q first, where the kernels read it), ∇V, D²V and the
        third derivatives side by side, so that one test covers all four."""
        model = self.model
        n, d, rows = model.n_dof, model.dim, model.bandwidth + 1
        values = np.zeros(d + n * (1 + 2 * rows))
        found = values[d:]
        self._local.buffers = (values[:d], values[:n], values, found[:n],
                               found[n:n * (1 + rows)].reshape(rows, n),
                               found[n * (1 + rows):].reshape(rows, n), np.ones(n))
        return self._local.buffers

    def _finite_at(self, x, all_finite=None):
        """Whether the state ``x`` (2N,) and the kernels there are all
        finite (what a kernel raises, it raises); the values are left in
        the buffers. ``all_finite``: the test of the values, compiled
        (:data:`varint.finite_values.ALL_FINITE`), else NumPy's."""
        model = self.model
        state, q, values, G, H, T, v = getattr(self._local, "buffers", None) or self._made()
        values.fill(0.0)     # a banded kernel need not write every entry
        state[:] = x
        par, resolved = model.params, self._resolved
        if resolved is None:
            resolved = tuple(Resolved.of(f) for f in checked_kernels(model))
            self._params, self._resolved = par, resolved
            self._compiled = all(type(f) is Resolved for f in resolved)
        grad, hess, third = resolved if par is self._params else checked_kernels(model)
        grad(q, par, G)
        hess(q, par, H)
        third(q, par, v, T)
        if all_finite is not None:
            return all_finite(values)
        return np.count_nonzero(np.isfinite(values)) == values.size    # (see states)

    def __call__(self, X, what="the initial state"):
        """Check the states ``X`` (M, 2N) as :func:`kernels` does."""
        model = self.model
        if len(X) != 1:
            kernels(model, X, what)
            return
        try:
            finite = self._finite_at(X[0])
        except Exception:
            kernels(model, X, what)    # raises, naming what is wrong
            raise
        if not finite:
            kernels(model, X, what)

    def states(self, x0):
        """(x (1, 2N), True) as :func:`states` gives them for one state
        ``x0``, where it is a float64 array of shape (2N,) finite with the
        kernels finite there, both tested in one pass (a prepared run's
        short call); None otherwise: then :func:`states` and this check,
        in that order, say what is wrong.

        The kernels are evaluated here before the state is known finite,
        so only where all three are compiled (:class:`Resolved`, as the
        first check resolved them): those warn about nothing and never
        stop on a NaN."""
        model = self.model
        if not (type(x0) is np.ndarray and (x0.dtype is _FLOAT64 or x0.dtype == _FLOAT64)
                and x0.shape == (model.dim,) and self._compiled
                and model.params is self._params):
            return None
        try:
            # (The values are a C-contiguous float64 vector of the kept
            # buffers, as ALL_FINITE's compiled version takes them.)
            if not self._finite_at(x0, self._all_finite):
                return None
        except Exception:
            return None
        # The same new array as states'.
        return x0[None].copy(), True


#: NumPy's float64 (the one object its arrays of native float64 share,
#: which ``is`` tests ~10x faster than ``==``).
_FLOAT64 = np.dtype(np.float64)


def _scan(model, Q):
    """The first row of ``Q`` where a kernel of ``model`` is not finite, −1
    if none; None where the compiled pass cannot call the kernels or one
    raises (then :func:`_evaluate` says why)."""
    kernels = checked_kernels(model)
    par = model.params
    if not (all(hasattr(k, "py_func") for k in kernels) and isinstance(par, np.ndarray)
            and par.dtype == np.float64 and par.ndim == 1 and par.flags.c_contiguous):
        return None
    from .kernels.finite import first_nonfinite

    try:
        return int(first_nonfinite(*kernels, Q, par, model.bandwidth + 1))
    except Exception:   # kernels of other types, or one raising: named from Python
        return None


#: :func:`_finite_from_source` runs the kernels' Python source for at most
#: this many coordinates (states × degrees of freedom): a built-in kernel
#: costs ~10–30 µs a state of a few degrees of freedom that way, against
#: ~3 ms to load each compiled kernel from numba's cache in a new process;
#: a long chain's site loops in Python would cost more than the loads.
_SOURCE_NUMBERS = 64
#: Kernels defined in these modules compile (the test suite compiles every
#: built-in model's), so only finiteness is left to check.
_BUILT_IN = "varint.models."


def _finite_from_source(model, Q):
    """True where the kernels of ``model`` are varint's own, not yet loaded
    in this process, and their Python source gives finite values at every
    row of ``Q`` without raising; False otherwise (then :func:`_evaluate`
    decides, on the compiled kernels, and names what is wrong).

    A new process's first run would otherwise load ∇V, D²V and the third
    derivatives from numba's cache only for this check (~10 ms, issue 28)
    while its stepper computes them itself. The source is what numba
    compiled; on NumPy float64 scalars its arithmetic is IEEE's, as the
    compiled code's (``error_model="numpy"``; a kernel with fast-math flags
    or with Python's error model divides by zero differently, and is
    checked compiled). Only the answer "finite" is taken from Python: any
    value that is not, any exception or warning turned error, goes to the
    compiled check, so every error message is the compiled check's.
    """
    kernels = checked_kernels(model)
    par = model.params
    if Q.size > _SOURCE_NUMBERS or not all(_unloaded_built_in(k) for k in kernels):
        return False
    n, rows = model.n_dof, model.bandwidth + 1
    G, H, T, v = np.empty(n), np.zeros((rows, n)), np.zeros((rows, n)), np.ones(n)
    grad, hess, third = (k.py_func for k in kernels)
    try:
        with np.errstate(all="ignore"):
            for q in Q:
                H.fill(0.0)
                T.fill(0.0)
                grad(q, par, G)
                hess(q, par, H)
                third(q, par, v, T)
                if not (np.isfinite(G).all() and np.isfinite(H).all()
                        and np.isfinite(T).all()):
                    return False
    except Exception:   # the compiled check decides, and names the error
        return False
    return True


def _unloaded_built_in(kernel):
    """``kernel`` is a numba function of :data:`_BUILT_IN` compiled with
    IEEE division (``error_model="numpy"``), no fast-math, and no
    compiled version of it is loaded yet in this process, whose source
    calls no other numba function (called from Python, each would be
    compiled in every process: a stencil's site and bond helpers are
    closures numba does not cache)."""
    options = getattr(kernel, "targetoptions", None)
    return (options is not None and not kernel.overloads
            and getattr(kernel.py_func, "__module__", "").startswith(_BUILT_IN)
            and options.get("error_model") == "numpy" and not options.get("fastmath")
            and not _calls_kernels(kernel.py_func))


def _calls_kernels(function):
    """Whether ``function`` reaches a numba function (one with a
    ``py_func``) through its closure or the globals its code names."""
    code = function.__code__
    scope = function.__globals__
    values = [c.cell_contents for c in function.__closure__ or ()]
    values += [scope[name] for name in code.co_names if name in scope]
    return any(hasattr(v, "py_func") for v in values)


def _evaluate(model, q_all, todo, what, total):
    """Evaluate the kernels at the rows ``todo`` of ``q_all`` from Python;
    raise for the first where one is not finite (see :func:`kernels`)."""
    from numba.core.errors import NumbaError

    n, rows = model.n_dof, model.bandwidth + 1
    block = max(1, min(len(todo), _KERNEL_BLOCK // (n * (2 * rows + 1))))
    v = np.ones(n)
    labels = ("the gradient ∇V", "the Hessian D²V", "the third derivatives of V")
    for start in range(0, len(todo), block):
        orbits = todo[start:start + block]
        Q = q_all[orbits]
        G = np.empty((len(Q), n))
        H = np.zeros((len(Q), rows, n))
        T = np.zeros((len(Q), rows, n))
        grad, hess, third = checked_kernels(model)
        try:
            for i in range(len(Q)):
                grad(Q[i], model.params, G[i])
                hess(Q[i], model.params, H[i])
                third(Q[i], model.params, v, T[i])
        except (NumbaError, TypeError) as exc:
            reason = first_line(exc)
            if reason.startswith("Int value is too large"):
                reason += ("; an integer beyond 64 bits, e.g. from (2*x)**100: write its "
                           "numbers with a decimal point, (2.0*x)**100")
            raise TypeError(
                f"the kernels of model {model.name!r} could not be compiled ({reason}); they "
                "must be numba functions grad(q, par, g), hess(q, par, B), third(q, par, v, B) "
                "writing float64 arrays in place, see varint.models.base") from exc
        except ArithmeticError as exc:
            raise ValueError(f"the derivatives of V ({model.name}) cannot be evaluated at "
                             f"{_where(what, orbits[i], total)}, q = {_short(Q[i])}: "
                             f"{type(exc).__name__}: {exc}") from None
        if np.isfinite(G).all() and np.isfinite(H).all() and np.isfinite(T).all():
            continue
        for label, values in zip(labels, (G, H, T), strict=True):
            bad = np.flatnonzero(~np.isfinite(values.reshape(len(Q), -1)).all(axis=1))
            if bad.size:
                i = int(bad[0])
                raise ValueError(
                    f"the derivatives of V ({model.name}) are not finite at "
                    f"{_where(what, orbits[i], total)}, q = {_short(Q[i])}: {label} is "
                    f"{_short(values[i].ravel())}; V is singular, not real or too large there "
                    "(start the orbit elsewhere)")


def _where(what, m, total):
    return what if total == 1 else f"{what} of orbit {m}"


def _short(q, limit=8):
    """A vector for a one-line message (a long one elided)."""
    q = np.asarray(q, dtype=float)
    if len(q) <= limit:
        return str(q.tolist())
    return f"[{', '.join(f'{v:g}' for v in q[:3])}, ... ({len(q)} values)]"


def first_line(exc):
    """The first line of ``exc``'s message that says something: numba's
    begin with "Failed in nopython mode pipeline" and may be coloured."""
    import re

    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
    lines = [line.strip() for line in text.splitlines()
             if line.strip() and not line.strip().startswith("Failed in ")]
    return lines[0] if lines else type(exc).__name__


# -- arguments of the public runs ----------------------------------------------
def model(value, name="model"):
    """``value`` if it is a varint model (a :class:`varint.models.Model` or a
    map model: it has ``kind``, ``dim`` and ``energy``); a name (e.g.
    ``"henon-heiles"``) or anything else is refused with the remedy. Checked
    by what a model has, not by class: the models import this module."""
    if isinstance(value, type) or not (
            getattr(value, "kind", None) in ("flow", "map")
            and isinstance(getattr(value, "dim", None), int)
            and callable(getattr(value, "energy", None))):
        hint = (" (varint.paper_orbit(name) returns a model and its initial state)"
                if isinstance(value, str) else "")
        raise ValueError(
            f"{name} must be a varint model (e.g. varint.models.HenonHeiles(), or "
            f"varint.models.from_potential(V, q)), got {type(value).__name__} {value!r}{hint}")
    return value


def dask_client(client, name="client"):
    """``client`` if it is None or looks like a ``dask.distributed.Client``
    (it has ``submit``, ``gather`` and ``scheduler_info``)."""
    if client is None or all(callable(getattr(client, a, None))
                             for a in ("submit", "gather", "scheduler_info")):
        return client
    raise ValueError(
        f"{name} must be a dask.distributed.Client or None, got {type(client).__name__} "
        f"{client!r}; e.g. Client('tcp://host:8786'), or Client(LocalCluster()) on this "
        "machine")


def method_options(method, given, valid, others=None):
    """Refuse options a method does not take, listing the ones it does.

    Parameters
    ----------
    method : str
        The ``method=`` name, e.g. ``"tm"``.
    given : mapping or iterable of str
        The options passed.
    valid : iterable of str
        The options ``method`` takes.
    others : mapping of str to iterable of str, optional
        Every method's options, to say which methods take a misplaced one.

    Raises
    ------
    TypeError
        ``"unknown option 'rtol' for method 'tm'; valid options: scheme,
        parallel, fast_indicators ('rtol' is an option of cvode, dop853)"``.
    """
    valid = list(valid)
    unknown = sorted(set(given) - set(valid))
    if not unknown:
        return
    bad = unknown[0]
    where = sorted(m for m, opts in (others or {}).items() if bad in opts and m != method)
    also = f" ({bad!r} is an option of {', '.join(where)})" if where else ""
    raise TypeError(f"unknown option {bad!r} for method {method!r}; valid options: "
                    f"{', '.join(valid) if valid else 'none'}{also}")


# -- files written at the end of a run ---------------------------------------------
def output_file(path, name="output file"):
    """Check, before any work, that ``path`` can be written at the end.

    The directory must exist, and the file must either be creatable there
    or exist and open for writing (without being changed). A symbolic link
    is refused (outside ``/dev``): it is replaced, never written through
    (:func:`varint.files.output_file`), so a link planted at the path by
    someone else cannot redirect the output onto another file. Files of virtual
    file systems such as ``/proc`` and ``/sys`` are kernel interfaces that
    refuse data or act on it, even for root: they are refused. Devices and
    pipes (``/dev/null``, ``/dev/stdout``) are accepted.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        Naming ``name``, the path and what is wrong with it.
    """
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"{name} must be a file path, got {type(path).__name__} {path!r}")
    text = os.fspath(path)
    if not text.strip():
        raise ValueError(f"{name} must name a file, got {text!r}")
    if "\0" in text:
        raise ValueError(f"{name} must be a file path, got {text!r} (it contains a NUL byte)")
    p = Path(text)
    try:
        # Inside: a name the system refuses (too long) fails lstat too.
        if p.is_symlink() and not is_device_path(p):
            raise ValueError(f"{name} {text} is a symbolic link (to {os.readlink(p)}); varint "
                             "does not write through links, whose target someone else may have "
                             "chosen: remove it or choose another path")
        if p.is_dir():
            raise ValueError(f"{name} {text} is a directory; expected a file path")
        parent = p.parent
        if not parent.exists():
            raise ValueError(f"{name} {text}: directory {parent} does not exist")
        if not parent.is_dir():
            raise ValueError(f"{name} {text}: {parent} is not a directory")
        if p.exists():
            # A virtual file system holds no blocks of storage.
            if p.is_file() and os.statvfs(p).f_blocks == 0:
                raise ValueError(f"cannot write {name} {text}: it is a file of a virtual file "
                                 "system (such as /proc or /sys), not a place for output")
            # O_NONBLOCK: a named pipe without a reader fails instead of
            # blocking; no O_TRUNC: the file is left as it is.
            os.close(os.open(p, os.O_WRONLY | os.O_APPEND | os.O_NONBLOCK))
        else:
            fd, probe = tempfile.mkstemp(dir=parent, prefix=".varint-", suffix=".probe")
            os.close(fd)
            os.unlink(probe)
    except OSError as exc:
        why = ("it is a named pipe that nothing reads" if exc.errno == errno.ENXIO
               else exc.strerror or str(exc))
        raise ValueError(f"cannot write {name} {text}: {why}") from None
    return p
