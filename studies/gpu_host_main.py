"""The host functions of a GPU map as they were at main 7b2b6c8, before
this round's changes to them (issue 33): the initial energies were the
host's (``varint.runspec._device_energies``) and each chunk computed them
again (``varint.maps.run_chunk`` without the map's reference),
the seeds' hash ran as ~70 vectorised passes (``varint.seeds._draw``),
the one-column full-rank check computed every length
(``varint._validate.full_rank``), and the pass over the initial states
tested them finite with three temporary arrays each
(``varint.kernels.finite.first_nonfinite``).

Used only by the benchmarks (``studies/gpu_stages.py --compare 3
--before host``, ``studies/bench_gpu.py``'s ``gpu_host_main`` contender),
which put them in the place of today's with :func:`host_of_main` (each is
looked up at its call), for the before/after ratio in one run on one
machine: the same values, bit for bit (the benchmarks compare them).
"""

from __future__ import annotations

import contextlib

import numpy as np
from numba import njit, types

from varint import _validate, maps, runspec, seeds
from varint.kernels import finite
from varint.seeds import _INIT_A, _INIT_B, _MASK64, _MIX_L, _MIX_R, _MULT_A, _MULT_B, \
    _PCG_MULT, _POOL, _normals

_SHIFT = np.uint32(16)


def _draw(seed, indices, shape, out):
    """``varint.seeds._draw`` at main 7b2b6c8."""
    words = _pcg_seed_words(seed, indices.astype(np.uint32))
    mult = np.array([_PCG_MULT >> 64, _PCG_MULT & _MASK64], dtype=np.uint64)
    _normals(words, mult, out.reshape(len(indices), -1))


def _pcg_seed_words(seed, indices):
    """``SeedSequence([seed, i]).generate_state(4, uint64)`` for every ``i``
    of ``indices`` (uint32), vectorised (``varint.seeds`` at main 7b2b6c8)."""
    m = len(indices)
    entropy = [np.full(m, seed, dtype=np.uint32), indices]
    h = np.uint32(_INIT_A)

    def hashmix(value):
        nonlocal h
        value = value ^ h
        h = h * np.uint32(_MULT_A)
        value = value * h
        return value ^ (value >> _SHIFT)

    def mix(x, y):
        r = np.uint32(_MIX_L) * x - np.uint32(_MIX_R) * y
        return r ^ (r >> _SHIFT)

    with np.errstate(over="ignore"):   # uint32 arithmetic wraps by design
        zero = np.zeros(m, dtype=np.uint32)
        pool = [hashmix(entropy[i] if i < len(entropy) else zero) for i in range(_POOL)]
        for src in range(_POOL):
            for dst in range(_POOL):
                if src != dst:
                    pool[dst] = mix(pool[dst], hashmix(pool[src]))
        words = np.empty((m, 2 * _POOL), dtype=np.uint32)
        h = np.uint32(_INIT_B)
        for i in range(2 * _POOL):
            value = pool[i % _POOL] ^ h
            h = h * np.uint32(_MULT_B)
            value = value * h
            words[:, i] = value ^ (value >> _SHIFT)
    # Pairs of uint32 read as little-endian uint64, as generate_state does.
    return words.astype("<u4").view("<u8").astype(np.uint64)


def full_rank(W, name="deviations"):
    """``varint._validate.full_rank`` at main 7b2b6c8."""
    if W.shape[2] == 0:
        return
    if W.shape[2] == 1:
        big = np.abs(W[:, :, 0]).max(axis=1)
        unit = np.divide(W[:, :, 0], big[:, None], out=np.zeros(W.shape[:2]),
                         where=big[:, None] > 0)
        s = (big * np.linalg.norm(unit, axis=1))[:, None]
    else:
        s = np.linalg.svd(W, compute_uv=False)
    rel = s[:, -1] / np.maximum(s[:, 0], np.finfo(float).tiny)
    bad = np.flatnonzero(~(rel > 1e-12))
    if bad.size:
        raise ValueError(
            f"{name} of orbit {bad[0]} are linearly dependent (smallest/largest singular value "
            f"{rel[bad[0]]:.3g}); expected k independent vectors")


@njit(types.int64(finite.GRAD, finite.HESS, finite.THIRD, finite._BAND, finite._VEC,
                  types.int64), cache=True)
def first_nonfinite(grad, hess, third, Q, par, rows):
    """``varint.kernels.finite.first_nonfinite`` at main 7b2b6c8."""
    n = Q.shape[1]
    g = np.empty(n)
    h = np.empty((rows, n))
    t = np.empty((rows, n))
    v = np.ones(n)
    for m in range(Q.shape[0]):
        h[:] = 0.0
        t[:] = 0.0
        q = Q[m]
        grad(q, par, g)
        hess(q, par, h)
        third(q, par, v, t)
        if not (np.isfinite(g).all() and np.isfinite(h).all() and np.isfinite(t).all()):
            return m
    return -1


_TODAY_RUN_CHUNK = maps.run_chunk


def run_chunk(x0, indices, spec, reference=None):
    """``varint.maps.run_chunk`` as main 7b2b6c8 called it: the chunk's run
    computes its orbits' reference again."""
    return _TODAY_RUN_CHUNK(x0, indices, spec)


def _device_energies(fields):
    """``varint.runspec._device_energies`` as main 7b2b6c8 had it: none
    (the initial energies on the host)."""
    return None


#: (owner, name, main 7b2b6c8's object) of the functions replaced.
REPLACED = ((seeds, "_draw", _draw), (_validate, "full_rank", full_rank),
            (finite, "first_nonfinite", first_nonfinite), (maps, "run_chunk", run_chunk),
            (runspec, "_device_energies", _device_energies))


@contextlib.contextmanager
def host_of_main():
    """Main 7b2b6c8's host functions in the place of today's, inside."""
    today = [(owner, name, getattr(owner, name)) for owner, name, _ in REPLACED]
    for owner, name, old in REPLACED:
        setattr(owner, name, old)
    try:
        yield
    finally:
        for owner, name, now in today:
            setattr(owner, name, now)
