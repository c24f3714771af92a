"""The right-hand side of the orbit and k deviation vectors, compiled from a
model's own kernels (for H = ½pᵀM⁻¹p + V(q) below; for any H(q, p),
ẋ = J∇H and Ẇ = J D²H W from the model's ∇H and D²H).

For H = ½ pᵀM⁻¹p + V(q) the equations of motion and the variational
equations (Skokos & Gerlach 2010, eqs. 6 and 7) are

    q̇ = M⁻¹p,   ṗ = −∇V(q),   δq̇ = M⁻¹δp,   δṗ = −D²V(q) δq,

with D²V from the model's band kernel, so a lattice stays matrix-free. The
flat state is ``y = (x, W.ravel())``: the orbit x = (q, p) of length 2N,
then the deviation vectors as the (2N, k) matrix W in row-major order —
the layout of ``RunState.W[m]`` and of heyoka's variational state. k is read
from the length of y, so one compiled function serves every k.

A time-dependent V(q, t) is integrated in the extended phase space, as by
the TM method (:mod:`varint.kernels.tm`): the flat state ends with the
*clock* (t, p_t), with ṫ = 1 and ṗ_t = −∂_tV, so y carries its own time
(every integrator may start a block at its own t = 0) and the momentum
conjugate to time for the conserved extended energy K = H + p_t. The
deviation vectors have δt = 0, so their equations are those above with D²V
at (q, t).

For a model that knows its potential symbolically and has few degrees of
freedom (the paper's orbits), the right-hand side is *generated*
(:func:`generated_rhs`): ∇V and D²V as straight-line expressions of q with
common subexpressions eliminated, no array allocated, the vectors' loop
summing in the band kernels' order — the code the TM stepper gets
(:mod:`varint.codegen`). It is the same function; on Hénon–Heiles
it gives the kernels' bits and costs a sixth of their time (no scratch
arrays), which makes a DOP853 interval of the paper's configuration
measurably cheaper (``studies/bench_baselines.py``).

The Jacobian of this right-hand side (:func:`tangent_jacobian`, for an
implicit integrator's Newton iteration) is exact and also matrix-free in
the vectors: with J = ∂ẏ/∂y,

    ∂q̇/∂p = M⁻¹,   ∂ṗ/∂q = −D²V,   ∂δq̇_j/∂δp_j = M⁻¹,   ∂δṗ_j/∂δq_j = −D²V,
    ∂δṗ_j/∂q = −D³V[δq_j],

the last from the model's third-derivative kernel (D³V[v] = Σ_k v_k
D²(∂_kV), symmetric), so J·v costs one Hessian and one third-derivative
evaluation.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
from functools import cache, lru_cache
from pathlib import Path

import numpy as np
from numba import njit

from varint import codecache
from varint.codegen.expressions import ensure_form, model_key
from varint.kernels.closures import cache_on_disk

__all__ = ["tangent_rhs", "tangent_jacobian", "generated_rhs", "kernel_rhs", "pack", "unpack", "clock_size",
           "CLOCK", "GENERATED_MAX_N"]

#: Entries of the clock (t, p_t) at the end of the flat state of a
#: time-dependent model.
CLOCK = 2
#: Largest N for which the right-hand side is generated as straight-line
#: code (that of the generated TM steppers); larger models use the kernels.
GENERATED_MAX_N = 16


def clock_size(model):
    """Length of the clock in the flat state of ``model``'s orbits: 2 for a
    time-dependent V, else 0."""
    return CLOCK if model.time_dependent else 0


def pack(x, W, out=None, clock=()):
    """The flat state (x, W.ravel(), *clock) of one orbit; ``W`` has shape
    (2N, k), ``clock`` is (t, p_t) for a time-dependent V."""
    d = x.shape[0]
    c = len(clock)
    if out is None:
        out = np.empty(d * (1 + W.shape[1]) + c, dtype=np.result_type(x, W))
    out[:d] = x
    out[d:len(out) - c] = W.ravel()
    if c:
        out[len(out) - c:] = clock
    return out


def unpack(y, d, clock=0):
    """Views (x, W) of a flat state with orbit dimension ``d`` = 2N and a
    clock of ``clock`` entries at its end."""
    return y[:d], y[d:len(y) - clock].reshape(d, -1)


def _with_fun(rhs):
    """``(rhs, fun)``: the in-place right-hand side ``rhs(t, y, yp)`` (the
    form SUNDIALS calls) and ``fun(t, y) -> yp`` around it (SciPy's form).

    These closures, and those of the right-hand sides and Jacobians below,
    are cached on disk (:func:`varint.kernels.closures.cache_on_disk`, named
    by what they close over): CVODE and SciPy call them from Python, so
    they are not compiled into a cached engine as DOP853's is, and the
    Jacobian CVODE uses took ~1.3 s to compile in every process."""

    @njit
    def fun(t, y):
        yp = np.empty_like(y)
        rhs(t, y, yp)
        return yp

    return rhs, cache_on_disk(fun)


@cache
def _compiled(grad, hess, n, bw, minv_bytes, par_bytes, dtime=None):
    minv = np.frombuffer(minv_bytes)
    par_model = np.frombuffer(par_bytes)
    d = 2 * n
    c = 0 if dtime is None else CLOCK

    @njit
    def rhs(t, y, yp):
        if c:
            # The clock (t, p_t) ends y; the kernels read t from par[-1].
            par = par_model.copy()
            par[-1] = y[y.shape[0] - 2]
        else:
            par = par_model
        # Orbit (eq. 6).
        q = y[:n].copy()
        g = np.empty(n)
        grad(q, par, g)
        for i in range(n):
            yp[i] = minv[i] * y[n + i]
            yp[n + i] = -g[i]
        if c:
            gt = np.empty(n)
            yp[y.shape[0] - 2] = 1.0
            yp[y.shape[0] - 1] = -dtime(q, par, gt)
        k = (y.shape[0] - d - c) // d
        if k == 0:
            return
        # Variational equations (eq. 7), D²V in band storage.
        B = np.zeros((bw + 1, n))
        hess(q, par, B)
        for i in range(n):
            a = minv[i]
            for j in range(k):
                yp[d + i * k + j] = a * y[d + (n + i) * k + j]
        for i in range(n):
            a = B[0, i]
            for j in range(k):
                yp[d + (n + i) * k + j] = -a * y[d + i * k + j]
        for b in range(1, bw + 1):
            for i in range(n - b):
                a = B[b, i]
                for j in range(k):
                    yp[d + (n + i) * k + j] -= a * y[d + (i + b) * k + j]
                    yp[d + (n + i + b) * k + j] -= a * y[d + i * k + j]

    return _with_fun(cache_on_disk(rhs))


@cache
def _compiled_hamiltonian(grad_hess, d, par_bytes, dtime=None):
    """The right-hand side of any H(q, p): ẋ = J∇H, Ẇ = J D²H W (from the
    model's kernel ``grad_hess(x, par, g, D)``), and the clock (t, p_t) of a
    time-dependent H, ṫ = 1, ṗ_t = −∂_tH."""
    par_model = np.frombuffer(par_bytes)
    n = d // 2
    c = 0 if dtime is None else CLOCK

    @njit
    def rhs(t, y, yp):
        if c:
            par = par_model.copy()
            par[-1] = y[y.shape[0] - 2]
        else:
            par = par_model
        x = y[:d].copy()
        g = np.empty(d)
        D = np.empty((d, d))
        grad_hess(x, par, g, D)
        for i in range(n):
            yp[i] = g[n + i]
            yp[n + i] = -g[i]
        if c:
            yp[y.shape[0] - 2] = 1.0
            yp[y.shape[0] - 1] = -dtime(x, par)
        k = (y.shape[0] - d - c) // d
        # Row i of W is y[d + i·k : d + (i + 1)·k]; (J D W)_i = (D W)_{n+i}, −(D W)_{i−n}.
        for i in range(d):
            src = n + i if i < n else i - n
            sign = 1.0 if i < n else -1.0
            for j in range(k):
                acc = 0.0
                for m in range(d):
                    acc += D[src, m] * y[d + m * k + j]
                yp[d + i * k + j] = sign * acc

    return _with_fun(cache_on_disk(rhs))


def _generated_source(V, n, minv, cached=False):
    """Source of a module defining ``rhs(t, y, yp)`` for the SymPy
    potential ``V`` in q0 … q{n−1} and the inverse masses ``minv``;
    ``cached``: compiled by numba on first call and kept in numba's disk
    cache beside the module's file (for :func:`varint.codecache.load_module`),
    else a plain function to compile in memory.

    SymPy and its printer are imported here, where a potential is worked
    on, not with this module: a process whose right-hand side is cached
    (:func:`generated_rhs`) never needs them (importing SymPy costs
    ~0.35 s, deriving and printing a potential's derivatives more)."""
    import sympy as sp  # type: ignore[import-untyped]

    from varint.models.symbolic import KernelPrinter

    q = sp.symbols(f"q0:{n}")
    g = [sp.diff(V, qi) for qi in q]
    H = {(i, j): sp.diff(g[i], q[j]) for i in range(n) for j in range(i, n)}
    H = {ij: e for ij, e in H.items() if e != 0}
    bw = max((j - i for i, j in H), default=0)
    printer = KernelPrinter()
    d = 2 * n
    head = ["from numba import njit", "", "", "@njit(cache=True)"] if cached else ["", ""]
    lines = ["import math", *head, "def rhs(t, y, yp):"]
    lines += [f"    q{i} = y[{i}]" for i in range(n)]
    for names, exprs, label in (([f"g{i}" for i in range(n)], g, "o"),
                                ([f"H{i}_{j}" for i, j in H], list(H.values()), "w")):
        temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(f"t{label}_"))
        lines += [f"    {t} = {printer.doprint(e)}" for t, e in temps]
        lines += [f"    {name} = {printer.doprint(e)}" for name, e in zip(names, reduced,
                                                                          strict=True)]

    def mass(i, term):
        return term if minv[i] == 1.0 else f"{minv[i]!r} * {term}"

    for i in range(n):
        lines.append(f"    yp[{i}] = {mass(i, f'y[{n + i}]')}")
        lines.append(f"    yp[{n + i}] = -g{i}")
    lines += [f"    k = (y.shape[0] - {d}) // {d}", "    for j in range(k):"]
    lines += [f"        a{i} = y[{d} + {i} * k + j]" for i in range(n)]
    for i in range(n):
        lines.append(f"        yp[{d} + {i} * k + j] = {mass(i, f'y[{d} + {n + i} * k + j]')}")
    for r in range(n):
        # The band kernels' order (baselines.rhs._compiled): for each
        # offset b, the entry left of the diagonal, then the right one.
        terms = []
        for b in range(bw + 1):
            for i, j, other in ((r - b, r, r - b), (r, r + b, r + b)):
                if b == 0 and i != r - b:
                    continue
                if i >= 0 and j < n and (i, j) in H and (b > 0 or not terms):
                    terms.append(f"H{i}_{j} * a{other}")
        lines.append(f"        yp[{d} + {n + r} * k + j] = "
                     + ("-" + " - ".join(terms) if terms else "0.0"))
    return "\n".join(lines) + "\n"


@lru_cache(maxsize=1)
def _generator_id():
    """A hash of what a generated right-hand side's source is made by: this
    module, the expression printer (``varint.models.symbolic``, found
    without importing it and so SymPy) and SymPy's version (its
    differentiation, CSE and printing)."""
    spec = importlib.util.find_spec("varint.models.symbolic")
    assert spec is not None and spec.origin is not None
    digest = hashlib.sha256(importlib.metadata.version("sympy").encode())
    for path in (Path(__file__), Path(spec.origin)):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _potential(model):
    """The model's SymPy potential in q0 … q{N−1}, and N."""
    import sympy as sp  # type: ignore[import-untyped]

    s = model.symbolic()
    n = len(s.q)
    return s.V.xreplace(dict(zip(s.q, sp.symbols(f"q0:{n}"), strict=True))), n


#: The generated right-hand sides of this process, by module name.
_GENERATED: dict[str, tuple] = {}


def _generated_module(model, key, minv):
    """:func:`generated_rhs` of a model whose symbolic form has the key
    ``key`` (:func:`varint.codegen.expressions.model_key`): a module in the
    kernels' cache directory (:func:`varint.codecache.load_module`, signed
    and verified before it runs) named by the generator, the form and the
    masses, so a later process loads it, and numba's compiled copy,
    without SymPy."""
    name = "varint_rhs_" + hashlib.sha256(
        f"{_generator_id()}|{key}|{minv!r}".encode()).hexdigest()[:24]
    if name not in _GENERATED:
        def make_source():
            # Only ever emitted from the model's own form: the stored facts
            # named the key, the model must give the same one.
            ensure_form(model, key)
            return _generated_source(*_potential(model), minv, cached=True)

        # Its kernel is cached on disk too (signed, verified before numba
        # loads it): CVODE calls it from Python, so it is not compiled into
        # a cached engine as DOP853's is, and was compiled in every process.
        _GENERATED[name] = _with_fun(codecache.load_module(name, "kernels", make_source).rhs)
    return _GENERATED[name]


@cache
def _compiled_generated(V, n, minv):
    # Keyed by the expression itself (SymPy expressions hash by structure):
    # no text is parsed back into an expression.
    namespace: dict = {}
    exec(compile(_generated_source(V, n, minv), "<varint generated rhs>", "exec"),
         namespace)
    rhs = njit(namespace["rhs"])

    return _with_fun(cache_on_disk(rhs))


def generated_rhs(model):
    """The right-hand side of :func:`tangent_rhs` as straight-line code
    generated from the model's SymPy potential, or None where it does not
    apply (no ``symbolic()``, a time-dependent V, N > :data:`GENERATED_MAX_N`).

    A model whose symbolic facts are known
    (:func:`varint.codegen.expressions.model_key`: kept signed in the cache
    directory for a built-in model) gets it from a generated module cached
    on disk, so a second process neither imports SymPy nor derives the
    potential again; any other is generated in memory, once per process.

    Returns
    -------
    (rhs, fun) or None
        As :func:`tangent_rhs`.
    """
    symbolic = getattr(model, "symbolic", None)
    if not callable(symbolic) or model.time_dependent or model.n_dof > GENERATED_MAX_N:
        return None
    minv = tuple(float(m) for m in model.inverse_mass)
    key = model_key(model)
    if key is not None:
        return _generated_module(model, key, minv)
    V, n = _potential(model)
    return _compiled_generated(V, n, minv)


def tangent_rhs(model):
    """Compiled right-hand sides of the orbit plus deviation vectors.

    Parameters
    ----------
    model : Model

    Returns
    -------
    rhs : numba function ``rhs(t, y, yp)``
        Fills ``yp`` in place (the form SUNDIALS calls).
    fun : numba function ``fun(t, y) -> yp``
        Returns a new array (the form SciPy calls).

    Notes
    -----
    Generated from the model's potential where :func:`generated_rhs`
    applies, else from its kernels; compiled once per model (cached for the
    process), so every propagator built for the same model shares them.
    For a time-dependent V the flat state ends with the clock (t, p_t)
    (see the module docstring) and ``t`` is not read. A model of any H(q, p)
    (:class:`~varint.models.hamiltonian.HamiltonianModel`) gives Hamilton's
    equations ẋ = J∇H and the variational equations Ẇ = J D²H W from its
    kernel of ∇H and D²H.
    """
    if callable(getattr(model, "grad_hess_h", None)):
        return _compiled_hamiltonian(
            model.grad_hess_h, model.dim,
            np.ascontiguousarray(model.params, dtype=np.float64).tobytes(),
            model.dtime_h if model.time_dependent else None)
    generated = generated_rhs(model)
    if generated is not None:
        return generated
    return kernel_rhs(model)


def kernel_rhs(model):
    """:func:`tangent_rhs` from the model's own kernels (every model but one of any H(q, p))."""
    return _compiled(model.grad_kernel, model.hess_kernel, model.n_dof, model.bandwidth,
                     np.ascontiguousarray(model.inverse_mass, dtype=np.float64).tobytes(),
                     np.ascontiguousarray(model.params, dtype=np.float64).tobytes(),
                     model.time_kernel if model.time_dependent else None)


@cache
def _compiled_jacobian(hess, third, n, bw, minv_bytes, par_bytes):
    minv = np.frombuffer(minv_bytes)
    par = np.frombuffer(par_bytes)
    d = 2 * n

    @njit
    def jac(t, y, yp, J):
        k = (y.shape[0] - d) // d
        J[:, :] = 0.0
        q = y[:n].copy()
        B = np.zeros((bw + 1, n))
        hess(q, par, B)
        # Block 0 is the orbit, block j + 1 deviation vector j: the same
        # [[0, M⁻¹], [−D²V, 0]] on the diagonal (row i + n of block b at
        # index o + i·s + c, with s = 1 for the orbit, s = k for vectors).
        for blk in range(k + 1):
            o, s, c = (0, 1, 0) if blk == 0 else (d, k, blk - 1)
            for i in range(n):
                J[o + i * s + c, o + (n + i) * s + c] = minv[i]
            for b in range(bw + 1):
                for i in range(n - b):
                    a = B[b, i]
                    J[o + (n + i) * s + c, o + (i + b) * s + c] -= a
                    if b:
                        J[o + (n + i + b) * s + c, o + i * s + c] -= a
        # ∂δṗ_j/∂q = −D³V[δq_j].
        v = np.empty(n)
        T = np.empty((bw + 1, n))
        for c in range(k):
            for m in range(n):
                v[m] = y[d + m * k + c]
            T[:, :] = 0.0
            third(q, par, v, T)
            for b in range(bw + 1):
                for i in range(n - b):
                    a = T[b, i]
                    J[d + (n + i) * k + c, i + b] -= a
                    if b:
                        J[d + (n + i + b) * k + c, i] -= a

    @njit
    def jac_times(t, y, yp, v, Jv):
        k = (y.shape[0] - d) // d
        q = y[:n].copy()
        B = np.zeros((bw + 1, n))
        hess(q, par, B)
        T = np.zeros((bw + 1, n))
        third(q, par, v[:n].copy(), T)
        for blk in range(k + 1):
            o, s, c = (0, 1, 0) if blk == 0 else (d, k, blk - 1)
            for i in range(n):
                Jv[o + i * s + c] = minv[i] * v[o + (n + i) * s + c]
                Jv[o + (n + i) * s + c] = 0.0
            for b in range(bw + 1):
                for i in range(n - b):
                    a = B[b, i]
                    Jv[o + (n + i) * s + c] -= a * v[o + (i + b) * s + c]
                    if b:
                        Jv[o + (n + i + b) * s + c] -= a * v[o + i * s + c]
            if blk:
                # −D³V[v_q] δq_c: D³V[v_q] δq_c = D³V[δq_c] v_q (symmetry).
                for b in range(bw + 1):
                    for i in range(n - b):
                        a = T[b, i]
                        Jv[d + (n + i) * k + c] -= a * y[d + (i + b) * k + c]
                        if b:
                            Jv[d + (n + i + b) * k + c] -= a * y[d + i * k + c]

    return cache_on_disk(jac), cache_on_disk(jac_times)


def tangent_jacobian(model):
    """The exact Jacobian ∂ẏ/∂y of :func:`tangent_rhs`'s right-hand side.

    Parameters
    ----------
    model : Model
        Time-independent (a time-dependent V has no kernel for ∂_t∇V).

    Returns
    -------
    jac : numba function ``jac(t, y, yp, J)``
        Fills the dense (len(y), len(y)) matrix ``J`` (the form of
        scikit-sundae's ``jacfn``).
    jac_times : numba function ``jac_times(t, y, yp, v, Jv)``
        Fills ``Jv`` with J·v without forming J (the form of
        scikit-sundae's ``CVODEJacTimes`` for its iterative solvers).

    Raises
    ------
    ValueError
        For a time-dependent model.
    """
    if model.time_dependent:
        raise ValueError(f"no exact Jacobian for the time-dependent model {model.name!r} "
                         "(its kernels give no derivative of the force in t)")
    return _compiled_jacobian(model.hess_kernel, model.third_kernel, model.n_dof,
                              model.bandwidth,
                              np.ascontiguousarray(model.inverse_mass, dtype=np.float64).tobytes(),
                              np.ascontiguousarray(model.params, dtype=np.float64).tobytes())
