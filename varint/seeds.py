"""Per-orbit random streams, seeded by (seed, orbit index), made fast.

Every orbit of a run or chaos map draws its deviation vectors from its own
stream, ``numpy.random.default_rng([seed, index])``, so its vectors do not
depend on how many orbits share a call or how a map is chunked
(:func:`varint.state.initial_deviations`). Building one NumPy generator per
orbit costs ~15 µs, mostly in ``SeedSequence``'s hashing written in Python:
for the 2000 orbits of a chaos map, 30 ms of serial work, a fifth of the
whole map.

:func:`standard_normals` gives the same numbers, bit for bit, in ~3 µs per
orbit: it runs ``SeedSequence``'s hash (M. E. O'Neill's ``seed_seq``
construction, as NumPy implements it) for all orbits at once in vectorised
uint32 arithmetic, seeds PCG64 from its output as NumPy does, and sets one
reused generator to each orbit's state. Entropy words outside uint32 (a seed
or index ≥ 2³²) take NumPy's own path, and so does everything if a NumPy
release seeds differently (checked once per process).
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["standard_normals"]

# SeedSequence's hash constants (pool of 4 uint32 words, 16-bit xorshift).
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
_SHIFT = np.uint32(16)
# PCG64's 128-bit LCG multiplier and mask.
_PCG_MULT = 0x2360ED051FC65DA44385DF649FCCF645
_MASK128 = (1 << 128) - 1


def standard_normals(seed, indices, shape):
    """``default_rng([seed, i]).standard_normal(shape)`` for each ``i`` of
    ``indices``, stacked: shape ``(len(indices),) + shape``.

    Parameters
    ----------
    seed : int
        Non-negative.
    indices : sequence of int
        Non-negative orbit indices.
    shape : tuple of int

    Returns
    -------
    ndarray of float64
    """
    indices = np.asarray(indices, dtype=np.int64).reshape(-1)
    out = np.empty((len(indices),) + tuple(shape))
    if not len(indices):
        return out
    if not (0 <= seed < 2 ** 32 and indices.min() >= 0 and indices.max() < 2 ** 32
            and _fast_path_is_numpys()):
        for m, index in enumerate(indices):
            out[m] = np.random.default_rng([seed, int(index)]).standard_normal(shape)
        return out
    _draw(int(seed), indices, shape, out)
    return out


@functools.cache
def _fast_path_is_numpys():
    """Whether this NumPy seeds as the fast path assumes (checked once per
    process against ``default_rng``, so a NumPy that changed its seeding
    falls back to the slow path instead of giving other numbers)."""
    probe = np.array([0, 1, 2 ** 31 + 5])
    want = np.array([np.random.default_rng([7, int(i)]).standard_normal(3) for i in probe])
    got = np.empty_like(want)
    _draw(7, probe, (3,), got)
    return got.tobytes() == want.tobytes()


def _draw(seed, indices, shape, out):
    """The fast path of :func:`standard_normals`, into ``out``."""
    words = _pcg_seed_words(seed, indices.astype(np.uint32)).tolist()
    bit_generator = np.random.PCG64(0)
    generator = np.random.Generator(bit_generator)
    state = {"bit_generator": "PCG64", "state": None, "has_uint32": 0, "uinteger": 0}
    for m, (s_hi, s_lo, i_hi, i_lo) in enumerate(words):
        # PCG64 seeded from (initstate, initseq): inc = 2·initseq + 1, then
        # two LCG steps around adding initstate (pcg_setseq_128_srandom_r).
        inc = (((i_hi << 64) | i_lo) << 1 | 1) & _MASK128
        x = (inc + ((s_hi << 64) | s_lo)) & _MASK128
        state["state"] = {"state": (x * _PCG_MULT + inc) & _MASK128, "inc": inc}
        bit_generator.state = state
        out[m] = generator.standard_normal(shape)


def _pcg_seed_words(seed, indices):
    """``SeedSequence([seed, i]).generate_state(4, uint64)`` for every ``i``
    of ``indices`` (uint32), shape (M, 4): the words PCG64 is seeded from."""
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
