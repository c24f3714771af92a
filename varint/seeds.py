"""Per-orbit random streams, seeded by (seed, orbit index), made fast.

Every orbit of a run or chaos map draws its deviation vectors from its own
stream, ``numpy.random.default_rng([seed, index])``, so its vectors do not
depend on how many orbits share a call or how a map is chunked
(:func:`varint.state.initial_deviations`). Building one NumPy generator per
orbit costs ~15 µs, mostly in ``SeedSequence``'s hashing written in Python:
for the 2000 orbits of a chaos map, 30 ms of serial work, a fifth of the
whole map.

:func:`standard_normals` gives the same numbers, bit for bit, in ~0.1 µs
per orbit of four normals: it runs ``SeedSequence``'s hash (M. E.
O'Neill's ``seed_seq`` construction, as NumPy implements it) for all orbits
at once in vectorised uint32 arithmetic, then one compiled loop seeds each
orbit's PCG64 from its words as NumPy does and draws NumPy's ziggurat
normals from it (NumPy's tables, as numba copies them). Entropy words
outside uint32 (a seed or index ≥ 2³²) take NumPy's own path, and so does
everything if a NumPy release seeds or draws differently (checked once per
process against ``default_rng``, over draws that reach the ziggurat's
slower branches). A process's first few hundred orbits take NumPy's
path (:data:`NUMPY_FIRST`): they cost less than loading the compiled loop.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit

try:   # NumPy's ziggurat tables, as numba's Generator support copies them
    from numba.np.random._constants import fi_double as _FI
    from numba.np.random._constants import ki_double as _KI
    from numba.np.random._constants import wi_double as _WI
    from numba.np.random._constants import ziggurat_nor_inv_r as _NOR_INV_R
    from numba.np.random._constants import ziggurat_nor_r as _NOR_R
    _TABLES = True
except ImportError:   # a numba without them: NumPy's own path
    _FI = _WI = np.zeros(256)
    _KI = np.zeros(256, dtype=np.uint64)
    _NOR_INV_R = _NOR_R = 0.0
    _TABLES = False

__all__ = ["standard_normals"]

# SeedSequence's hash constants (pool of 4 uint32 words, 16-bit xorshift).
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
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
            and not _numpy_first(len(indices)) and _fast_path_is_numpys()):
        for m, index in enumerate(indices):
            out[m] = np.random.default_rng([seed, int(index)]).standard_normal(shape)
        return out
    _draw(int(seed), indices, shape, out)
    return out


#: Orbits a process draws with NumPy's own generator (~10 µs an orbit)
#: before it loads the compiled loop and checks it (:func:`_fast_path_is_numpys`,
#: ~5 ms, as long as ~500 orbits): a process's first small runs (one orbit
#: for a spectrum) do not wait for it, a map or a series of runs gets it.
#: Both paths give the same numbers.
NUMPY_FIRST = 512
_numpy_drawn = 0


def _numpy_first(n):
    """Whether ``n`` more orbits are drawn with NumPy's generator
    (:data:`NUMPY_FIRST`); counts them if so."""
    global _numpy_drawn
    if _numpy_drawn + n > NUMPY_FIRST:
        return False
    _numpy_drawn += n
    return True


@functools.cache
def _fast_path_is_numpys():
    """Whether this NumPy seeds as the fast path assumes (checked once per
    process against ``default_rng``, so a NumPy that changed its seeding
    falls back to the slow path instead of giving other numbers)."""
    if not _TABLES:
        return False
    # 2048 draws: ~14 take the ziggurat's slower branches.
    probe = np.r_[0, 1, 2 ** 31 + 5, np.arange(1000, 1061)]
    want = np.array([np.random.default_rng([7, int(i)]).standard_normal(32) for i in probe])
    got = np.empty_like(want)
    _draw(7, probe, (32,), got)
    return got.tobytes() == want.tobytes()


def _draw(seed, indices, shape, out):
    """The fast path of :func:`standard_normals`, into ``out``: the seed
    words of every orbit at once (:func:`_pcg_seed_words`), then every
    orbit's PCG64 stream and normals in one compiled loop
    (:func:`_normals`)."""
    words = _pcg_seed_words(np.uint64(seed), indices.astype(np.uint64))
    mult = np.array([_PCG_MULT >> 64, _PCG_MULT & _MASK64], dtype=np.uint64)
    _normals(words, mult, out.reshape(len(indices), -1))


# -- PCG64 and NumPy's ziggurat, compiled -----------------------------------------
# A 128-bit integer is a (high, low) pair of uint64; every constant is a
# uint64 so that numba never mixes it with a signed integer (which would
# give a float).
_MASK64 = (1 << 64) - 1
_U1, _U8, _U11, _U32, _U58, _U63 = (np.uint64(v) for v in (1, 8, 11, 32, 58, 63))
_LOW32 = np.uint64(0xFFFFFFFF)
_BYTE = np.uint64(0xFF)
_MANTISSA = np.uint64(0x000FFFFFFFFFFFFF)
_TO_UNIT = 1.0 / 9007199254740992.0     # 2**-53: next_double's scale


@njit(inline="always")
def _mul_high(a, b):
    """The high 64 bits of the 128-bit product of uint64 ``a`` and ``b``."""
    a_lo, a_hi = a & _LOW32, a >> _U32
    b_lo, b_hi = b & _LOW32, b >> _U32
    lo_lo = a_lo * b_lo
    mid1 = a_hi * b_lo + (lo_lo >> _U32)
    mid2 = a_lo * b_hi + (mid1 & _LOW32)
    return a_hi * b_hi + (mid1 >> _U32) + (mid2 >> _U32)


@njit(inline="always")
def _lcg(hi, lo, m_hi, m_lo, i_hi, i_lo):
    """(hi, lo)·(m_hi, m_lo) + (i_hi, i_lo) mod 2¹²⁸: one step of PCG64's LCG."""
    p_hi = _mul_high(lo, m_lo) + hi * m_lo + lo * m_hi
    p_lo = lo * m_lo
    s_lo = p_lo + i_lo
    carry = _U1 if s_lo < p_lo else np.uint64(0)
    return p_hi + i_hi + carry, s_lo


@njit(inline="always")
def _output(hi, lo):
    """PCG64's output of a state: XSL-RR, (hi ⊕ lo) rotated right by the top
    6 bits of the state."""
    v = hi ^ lo
    r = hi >> _U58
    return (v >> r) | (v << ((np.uint64(64) - r) & _U63))


@njit(cache=True, error_model="numpy")
def _normals(words, mult, out):
    """``out[m]`` filled with standard normals of orbit m's stream: PCG64
    seeded from ``words[m]`` = (initstate high, low, initseq high, low) as
    ``pcg_setseq_128_srandom_r`` seeds it (inc = 2·initseq + 1, then two
    LCG steps around adding initstate), then NumPy's
    ``random_standard_normal`` (Marsaglia & Tsang's ziggurat, 256
    layers, NumPy's tables), draw by draw.

    References
    ----------
    M. E. O'Neill, "PCG: a family of simple fast space-efficient
    statistically good algorithms for random number generation", HMC-CS-2014-0905.
    G. Marsaglia and W. W. Tsang, "The ziggurat method for generating random
    variables", J. Stat. Softw. 5 (2000).
    """
    m_hi, m_lo = mult[0], mult[1]
    for m in range(out.shape[0]):
        s_hi, s_lo, q_hi, q_lo = words[m, 0], words[m, 1], words[m, 2], words[m, 3]
        i_hi = (q_hi << _U1) | (q_lo >> _U63)
        i_lo = (q_lo << _U1) | _U1
        x_lo = i_lo + s_lo
        x_hi = i_hi + s_hi + (_U1 if x_lo < i_lo else np.uint64(0))
        hi, lo = _lcg(x_hi, x_lo, m_hi, m_lo, i_hi, i_lo)
        for j in range(out.shape[1]):
            while True:
                hi, lo = _lcg(hi, lo, m_hi, m_lo, i_hi, i_lo)
                r = _output(hi, lo)
                idx = r & _BYTE
                r = r >> _U8
                rabs = (r >> _U1) & _MANTISSA
                x = float(rabs) * _WI[idx]
                if r & _U1:
                    x = -x
                if rabs < _KI[idx]:
                    out[m, j] = x       # 99.3 % of the draws
                    break
                if idx == 0:
                    # The tail beyond r, by Marsaglia's exponential pair.
                    while True:
                        hi, lo = _lcg(hi, lo, m_hi, m_lo, i_hi, i_lo)
                        u1 = float(_output(hi, lo) >> _U11) * _TO_UNIT
                        hi, lo = _lcg(hi, lo, m_hi, m_lo, i_hi, i_lo)
                        u2 = float(_output(hi, lo) >> _U11) * _TO_UNIT
                        xx = -_NOR_INV_R * math.log1p(-u1)
                        yy = -math.log1p(-u2)
                        if yy + yy > xx * xx:
                            out[m, j] = (-(_NOR_R + xx) if (rabs >> _U8) & _U1
                                         else _NOR_R + xx)
                            break
                    break
                hi, lo = _lcg(hi, lo, m_hi, m_lo, i_hi, i_lo)
                u = float(_output(hi, lo) >> _U11) * _TO_UNIT
                if (_FI[idx - 1] - _FI[idx]) * u + _FI[idx] < math.exp(-0.5 * x * x):
                    out[m, j] = x
                    break


_U16 = np.uint64(16)


@njit(cache=True)
def _pcg_seed_words(seed, indices):
    """``SeedSequence([seed, i]).generate_state(4, uint64)`` for every ``i``
    of ``indices`` (non-negative, below 2³²), shape (M, 4): the words PCG64
    is seeded from, one orbit at a time (NumPy's ``mix_entropy`` and
    ``generate_state`` on a pool of four uint32 words, each product and
    difference reduced mod 2³²; a uint64 holds the uint32 arithmetic).
    Compiled: the vectorised form made ~70 passes over arrays of M
    numbers, 0.25 s for 10⁶ orbits."""
    m = len(indices)
    out = np.empty((m, 4), dtype=np.uint64)
    pool = np.empty(_POOL, dtype=np.uint64)
    words = np.empty(2 * _POOL, dtype=np.uint64)
    mult_a, mult_b = np.uint64(_MULT_A), np.uint64(_MULT_B)
    mix_l, mix_r = np.uint64(_MIX_L), np.uint64(_MIX_R)
    for j in range(m):
        h = np.uint64(_INIT_A)
        for i in range(_POOL):
            value = np.uint64(seed) if i == 0 else (
                np.uint64(indices[j]) if i == 1 else np.uint64(0))
            # hashmix
            value = value ^ h
            h = (h * mult_a) & _LOW32
            value = (value * h) & _LOW32
            pool[i] = value ^ (value >> _U16)
        for src in range(_POOL):
            for dst in range(_POOL):
                if src != dst:
                    value = pool[src] ^ h
                    h = (h * mult_a) & _LOW32
                    value = (value * h) & _LOW32
                    value = value ^ (value >> _U16)
                    # mix(pool[dst], hashmix(pool[src]))
                    r = ((mix_l * pool[dst]) - (mix_r * value)) & _LOW32
                    pool[dst] = r ^ (r >> _U16)
        h = np.uint64(_INIT_B)
        for i in range(2 * _POOL):
            value = pool[i % _POOL] ^ h
            h = (h * mult_b) & _LOW32
            value = (value * h) & _LOW32
            words[i] = value ^ (value >> _U16)
        # Pairs of uint32 read as little-endian uint64, as generate_state does.
        for i in range(_POOL):
            out[j, i] = words[2 * i] | (words[2 * i + 1] << _U32)
    return out
