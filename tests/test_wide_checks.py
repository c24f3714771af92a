"""The orbit check in vector lanes (``orbit_status_wide``) answers as the
chained one (``orbit_status``) on every state: ordinary, escaping by one
ulp, holding NaN or infinity, near overflow."""

import numpy as np
import pytest
from numba import njit

from varint.kernels.checks import orbit_status, orbit_status_wide, square_sums
from varint.protocol import Status


@njit
def _both(x, n, escape_r2):
    return orbit_status(x, n, escape_r2), orbit_status_wide(x, n, escape_r2)


@njit
def _chained_sums(x, n):
    rq = 0.0
    rp = 0.0
    for i in range(n):
        rq += x[i] * x[i]
        rp += x[n + i] * x[n + i]
    return rq, rp


def _states(rng):
    """(state, n) pairs: plain, huge, tiny, with NaN or infinity planted."""
    for n in (1, 2, 3, 7, 8, 9, 63, 64, 65, 1000, 4096):
        for scale in (1.0, 1e-160, 1e150, 1e154, 3e307):
            x = rng.standard_normal(2 * n) * scale
            yield x, n
            for bad in (np.nan, np.inf, -np.inf):
                y = x.copy()
                y[rng.integers(2 * n)] = bad
                yield y, n


def test_square_sums_within_the_bound_of_any_order():
    # |Σ_fast − Σ_chained| ≤ 2γ_n Σ (Higham 2002, eq. 4.4), γ_n = nu/(1 − nu).
    rng = np.random.default_rng(1)
    u = 2.0 ** -53
    for n in (1, 5, 64, 1000, 4096):
        x = rng.standard_normal(2 * n) * rng.uniform(0.1, 10.0, 2 * n)
        fast, chained = square_sums(x, n), _chained_sums(x, n)
        gamma = n * u / (1 - n * u)
        for f, c in zip(fast, chained, strict=True):
            assert abs(f - c) <= 2 * gamma * c


@pytest.mark.parametrize("where", ["far", "at", "below", "above", "inf", "zero"])
def test_same_status_as_the_chained_check(where):
    rng = np.random.default_rng(7)
    seen = set()
    for x, n in _states(rng):
        rq = _chained_sums(x, n)[0]
        escape_r2 = {"far": 4.0 * rq + 1.0, "at": rq,
                     "below": np.nextafter(rq, 0.0), "above": np.nextafter(rq, np.inf),
                     "inf": np.inf, "zero": 0.0}[where]
        chained, wide = _both(x, n, escape_r2)
        assert wide == chained, (n, where, x[:4], escape_r2)
        seen.add(chained)
    # The cases reach the answers of the chained check they should.
    ok, escaped, bad = int(Status.OK), int(Status.ESCAPED), int(Status.ORBIT_NONFINITE)
    expected = {"below": {escaped, bad}, "zero": {escaped, bad}}.get(where, {ok, bad})
    assert seen == expected
