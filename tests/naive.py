"""Slow, obvious NumPy versions of what the compiled kernels do, written
straight from the paper's formulas, to test the kernels against."""

import numpy as np


def hh_tm_sbab2c_step(x, W, tau):
    """One SBAB2C step of the TM method for Hénon–Heiles, from the explicit
    maps of the paper's Appendix A: e^{τL_AV} (A.21), e^{τL_BV} (A.22) and
    e^{τL_CV} (A.23), with S = C(−gτ³/2) B(τ/6) A(τ/2) B(2τ/3) A(τ/2)
    B(τ/6) C(−gτ³/2), g = 1/72."""
    x = np.array(x, dtype=float)
    W = np.array(W, dtype=float)

    def drift(h):
        x[0:2] += h * x[2:4]
        W[0:2] += h * W[2:4]

    def kick(h):
        q0, q1 = x[0], x[1]
        x[2] -= h * q0 * (1 + 2 * q1)
        x[3] += h * (q1 * q1 - q0 * q0 - q1)
        D = np.array([[1 + 2 * q1, 2 * q0], [2 * q0, 1 - 2 * q1]])
        W[2:4] -= h * D @ W[0:2]

    def corrector(h):
        q0, q1 = x[0], x[1]
        x[2] -= h * 2 * q0 * (1 + 2 * q0 ** 2 + 6 * q1 + 2 * q1 ** 2)
        x[3] -= h * 2 * (q1 - 3 * q1 ** 2 + 2 * q1 ** 3 + 3 * q0 ** 2 + 2 * q0 ** 2 * q1)
        D = 2 * np.array([[1 + 6 * q0 ** 2 + 2 * q1 ** 2 + 6 * q1, 2 * q0 * (3 + 2 * q1)],
                          [2 * q0 * (3 + 2 * q1), 1 + 2 * q0 ** 2 + 6 * q1 ** 2 - 6 * q1]])
        W[2:4] -= h * D @ W[0:2]

    hc = -(1 / 72) * tau ** 3 / 2
    corrector(hc)
    kick(tau / 6)
    drift(tau / 2)
    kick(2 * tau / 3)
    drift(tau / 2)
    kick(tau / 6)
    corrector(hc)
    return x, W


def qr_positive(W):
    """QR with a positive diagonal of R, by LAPACK (Householder)."""
    Q, R = np.linalg.qr(W)
    s = np.sign(np.diag(R))
    return Q * s, (R.T * s).T


def fd_gradient(f, q, h=1e-5):
    """Central finite-difference gradient of a scalar function."""
    q = np.asarray(q, dtype=float)
    g = np.empty_like(q)
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        g[i] = (f(q + e) - f(q - e)) / (2 * h)
    return g


def fd_jacobian(f, q, h=1e-5):
    """Central finite-difference Jacobian of a vector function."""
    q = np.asarray(q, dtype=float)
    cols = []
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        cols.append((np.asarray(f(q + e)) - np.asarray(f(q - e))) / (2 * h))
    return np.stack(cols, axis=-1)
