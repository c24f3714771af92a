"""Slow, obvious NumPy versions of one interval of each TDH method for
Hénon–Heiles, written straight from the paper's Appendix A, to test the
compiled kernels against. The orbit takes the TM method's SBAB2C steps
(:func:`tests.naive.hh_tm_sbab2c_step`, the paper's maps A.5–A.8)."""

import math

import numpy as np

from tests.naive import hh_tm_sbab2c_step

G_SBAB2C = 1.0 / 72.0


def _orbit(x, h):
    x, _ = hh_tm_sbab2c_step(x, np.zeros((4, 0)), h)
    return x


def _hessian(q):
    # Eq. (A.12).
    x, y = q
    return np.array([[1 + 2 * y, 2 * x], [2 * x, 1 - 2 * y]])


def _tdh_sbab2c(W, tau, q_at):
    """SBAB2C on the (extended) TDH over τ: the maps e^{τL_Ã} (A.15),
    e^{τL_B̃} (A.16) and e^{τL_C̃} (A.18), with the orbit position of each
    kick given by ``q_at(c)`` for the time t_i + cτ."""
    W = np.array(W, dtype=float)

    def drift(h):
        W[0:2] += h * W[2:4]

    def kick(h, q):
        x, y = q
        dx, dy = W[0].copy(), W[1].copy()
        W[2] -= ((1 + 2 * y) * dx + 2 * x * dy) * h
        W[3] += (-2 * x * dx + (-1 + 2 * y) * dy) * h

    def corrector(h, q):
        x, y = q
        dx, dy = W[0].copy(), W[1].copy()
        W[2] -= 2 * (4 * x * dy + (4 * x * x + (1 + 2 * y) ** 2) * dx) * h
        W[3] -= 2 * (4 * x * dx + (4 * x * x + (1 - 2 * y) ** 2) * dy) * h

    hc = -G_SBAB2C * tau ** 3 / 2
    corrector(hc, q_at(0.0))
    kick(tau / 6, q_at(0.0))
    drift(tau / 2)
    kick(2 * tau / 3, q_at(0.5))
    drift(tau / 2)
    kick(tau / 6, q_at(1.0))
    corrector(hc, q_at(1.0))
    return W


def hh_tdhcc_interval(x, W, tau):
    """TDHcc, SBAB2C for orbit and frozen TDH, Δt = τ: returns (x, W)."""
    q = np.array(x[:2])
    return _orbit(x, tau), _tdh_sbab2c(W, tau, lambda c: q)


def hh_tdheps_interval(x, W, tau):
    """TDHeps, SBAB2C with τ = 2Δt on the extended TDH (A.13–A.18), the
    orbit at t_i, t_i + Δt, t_i + 2Δt: returns (x, W)."""
    x1 = _orbit(x, tau / 2)
    x2 = _orbit(x1, tau / 2)
    grid = {0.0: x[:2], 0.5: x1[:2], 1.0: x2[:2]}
    return x2, _tdh_sbab2c(W, tau, lambda c: grid[c])


def paper_transform(x, y):
    """Eq. (A.10) exactly as printed (ill-conditioned for y < 0, |x| ≪ |y|)."""
    r = math.sqrt(x * x + y * y)
    a = math.sqrt(x * x + y * y + y * r)
    return np.array([[a / (math.sqrt(2) * r), -x / (math.sqrt(2) * a)],
                     [x * a / (math.sqrt(2) * r * (r + y)), (r + y) / (math.sqrt(2) * a)]])


def hh_tdhes_interval(x, W, tau):
    """TDHes from the paper's transformation: δq = TδQ, δp = TδP (A.9–A.10)
    makes the frozen TDH the oscillators ½(δP² + λδQ²) of (A.11),
    λ = 1 ± 2r, solved with a complex frequency √λ (so a negative λ gives
    cosh and sinh); needs x ≠ 0 and λ ≠ 0."""
    q = x[:2]
    T = paper_transform(*q)
    r = math.hypot(*q)
    W = np.array(W, dtype=float)
    Q, P = T.T @ W[:2], T.T @ W[2:]
    for row, lam in enumerate((1 + 2 * r, 1 - 2 * r)):
        w = np.sqrt(complex(lam))
        c, s = np.cos(w * tau), np.sin(w * tau)
        Q[row], P[row] = ((c * Q[row] + s / w * P[row]).real,
                          (-w * s * Q[row] + c * P[row]).real)
    return _orbit(x, tau), np.vstack([T @ Q, T @ P])
