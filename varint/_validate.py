"""Input checks shared by the public API: each names the bad value and what
was expected, before anything reaches a compiled kernel."""

from __future__ import annotations

import numbers

import numpy as np


def positive_float(value, name):
    """``value`` as a float that is finite and > 0."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return value


def horizon(t_end, tau):
    """``(t_end, tau)`` checked: both finite, τ > 0, t_end ≥ τ."""
    tau = positive_float(tau, "tau")
    if isinstance(t_end, bool) or not isinstance(t_end, numbers.Real) or not np.isfinite(t_end):
        raise ValueError(f"t_end must be a finite number, got {t_end!r}")
    t_end = float(t_end)
    if t_end < 0:
        raise ValueError(f"t_end must be >= 0, got {t_end!r}")
    if t_end < tau * (1 - 1e-12):
        raise ValueError(f"t_end = {t_end!r} is shorter than one step tau = {tau!r}")
    return t_end, tau


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


def output_times(t_out, name="t_out"):
    """``t_out`` as None, a positive integer count, or a 1-D float array of
    times (see :func:`varint.state.output_steps` for their meaning)."""
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
    return t


def states(model, x0, name="x0"):
    """Initial states as a float64 array of shape (M, 2N), and whether the
    caller passed a single state (so results are squeezed)."""
    x = real_array(x0, name)
    dim = model.dim
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


def full_rank(W, name="deviations"):
    """Raise if the k columns of any (2N, k) block are linearly dependent."""
    if W.shape[2] == 0:
        return
    s = np.linalg.svd(W, compute_uv=False)
    rel = s[:, -1] / np.maximum(s[:, 0], np.finfo(float).tiny)
    bad = np.flatnonzero(~(rel > 1e-12))
    if bad.size:
        raise ValueError(
            f"{name} of orbit {bad[0]} are linearly dependent (smallest/largest singular value "
            f"{rel[bad[0]]:.3g}); expected k independent vectors")


def orthonormal(W, name="deviations", tol=1e-10):
    """Raise unless every (2N, k) block has orthonormal columns."""
    full_rank(W, name)
    k = W.shape[2]
    err = np.abs(np.einsum("mik,mil->mkl", W, W) - np.eye(k)).max(axis=(1, 2))
    bad = np.flatnonzero(err > tol)
    if bad.size:
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
