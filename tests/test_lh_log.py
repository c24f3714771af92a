"""varint.kernels.lh_log: the LH steppers' logarithm is ``vlog`` bit for bit
(whose accuracy ``tests/test_logarithm.py`` proves), computed without a
branch, as a loop over lanes takes it; the LH module of a logarithmic
potential prints it, and its lanes keep the one-orbit kernel's bits."""

import math

import numpy as np
import sympy as sp

from numba import njit

from varint.kernels.lh_log import lane_log
from varint.kernels.logarithm import vlog


@njit(error_model="numpy")
def _both(xs, a, b):
    for i in range(xs.size):
        a[i] = vlog(xs[i])
    # A loop over many values, as the lanes take it (vectorised).
    for i in range(xs.size):
        b[i] = lane_log(xs[i])


def _arguments():
    rng = np.random.default_rng(22)
    eps = np.finfo(float).eps
    return np.concatenate([
        rng.integers(0, 2 ** 63, 200_000, dtype=np.int64).view(np.float64),   # every bit pattern
        -rng.integers(1, 2 ** 63, 1000, dtype=np.int64).view(np.float64),     # negatives
        np.exp2(rng.uniform(-1074, 1024, 20_000)),                             # every binade
        rng.uniform(0.5, 2.0, 20_000),
        1.0 + rng.integers(-4096, 4096, 4000) * eps,                           # near 1
        1.0 + rng.uniform(-2 ** -19, 2 ** -19, 4000),                          # |f| < 2^-20
        np.sqrt(0.5) * (1 + rng.uniform(-1e-6, 1e-6, 2000)),
        np.sqrt(2.0) * (1 + rng.uniform(-1e-6, 1e-6, 2000)),
        np.array([0.0, -0.0, math.inf, -math.inf, math.nan, -math.nan, 1.0, 2.0, 0.5,
                  5e-324, 2.2250738585072014e-308, 2.2250738585072014e-308 * (1 - 2 ** -52),
                  1.7976931348623157e308, 0.0009]),
    ])


def test_lane_log_is_vlog_bit_for_bit():
    xs = _arguments()
    a, b = np.empty_like(xs), np.empty_like(xs)
    _both(xs, a, b)
    same = (a.view(np.int64) == b.view(np.int64)) | (np.isnan(a) & np.isnan(b))
    assert same.all(), xs[~same][:5]


def test_lane_log_special_values():
    xs = np.array([1.0, 0.0, -0.0, -1.0, math.inf, math.nan])
    a, b = np.empty_like(xs), np.empty_like(xs)
    _both(xs, a, b)
    assert b[0] == 0.0 and math.copysign(1.0, b[0]) == 1.0
    assert b[1] == -math.inf and b[2] == -math.inf
    assert math.isnan(b[3]) and b[4] == math.inf and math.isnan(b[5])


def test_lane_log_within_one_ulp_of_the_c_library():
    # Both within 1 ulp of the correctly rounded value (fdlibm 0.79, glibc
    # 0.51): at most one unit apart, as integers of the same binade.
    rng = np.random.default_rng(5)
    xs = np.concatenate([np.exp2(rng.uniform(-1000, 1000, 20_000)), rng.uniform(1e-3, 10, 20_000)])
    a, b = np.empty_like(xs), np.empty_like(xs)
    _both(xs, a, b)
    c = np.log(xs)
    assert np.all(np.abs(b.view(np.int64) - c.view(np.int64)) <= 1)


def test_the_lh_module_of_a_logarithmic_potential_prints_lane_log():
    from varint.codegen.lh import Flow, lh_source

    x, y, px, py = sp.symbols("x y px py")
    V = sp.log(sp.Float(0.03) ** 2 + x ** 2 + y ** 2) / 2
    src = lh_source((px ** 2 + py ** 2) / 2, V, [x, y], [px, py], Flow("free", (1.0, 1.0)),
                    (0, 1, 0))
    assert "lane_log(" in src and "math.log(_" not in src
    # The potential's group runs in a loop of its own (varint.codegen.lh_lanes).
    lanes1 = src[src.index("def lanes1"):]
    assert any(line.strip().startswith("v = (1/2)*lane_log(") for line in lanes1.splitlines())
