"""Plots of results in the paper's style: log-log X_i(t) with a 1/t guide,
GALI_k(t) with the power laws of regular motion.

matplotlib is imported lazily, so the rest of varint never needs it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_lyapunov", "plot_gali", "plot_sali"]


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(5, 3.6), layout="constrained")
    return ax


def _guide(ax, t, y_end, power, label=None, color="k", decades=3.0):
    """A power law t^power through the last point, over the last decades
    (where the asymptotic law should hold)."""
    t = np.asarray(t, dtype=float)
    t = t[t >= t[-1] * 10.0 ** -decades]
    ax.loglog(t, y_end * (t / t[-1]) ** power, "--", color=color, lw=0.8, label=label)


def plot_lyapunov(result, ax=None, which=None, guide=True):
    """log-log X_i(t) for the exponents ``which`` (default: the positive
    half, X_1 … X_N), with a 1/t line (paper eq. 11).

    Parameters
    ----------
    result : LyapunovResult
        A single-orbit result.
    ax : matplotlib Axes, optional
    which : sequence of int, optional
        Zero-based exponent indices.
    guide : bool
        Draw the ∝ 1/t law of regular orbits.
    """
    ax = _axes(ax)
    X = np.asarray(result.exponents)
    if X.ndim != 2:
        raise ValueError("plot_lyapunov takes a single-orbit result; index the batch first")
    which = range(max(1, X.shape[1] // 2)) if which is None else which
    for i in which:
        ax.loglog(result.t, np.abs(X[:, i]), label=f"$|X_{{{i + 1}}}|$")
    if guide:
        _guide(ax, result.t, abs(X[-1, 0]), -1.0, r"$\propto t^{-1}$")
    ax.set_xlabel("t")
    ax.set_ylabel("finite-time LCE")
    ax.legend(fontsize=8)
    return ax


def plot_gali(result, ax=None, n_dof=None, guide=True):
    """GALI_k(t) on log-log axes, with the regular-orbit laws
    GALI_k ∝ t^{−2(k−N)} for k > N (paper eq. 15) when ``guide``.

    ``n_dof`` (torus dimension N) defaults to half the phase-space
    dimension of the model in the result's provenance.
    """
    ax = _axes(ax)
    n = n_dof or result.provenance.model.get("n_dof")
    for k, g in sorted(result.gali.items()):
        g = np.asarray(g)
        if g.ndim != 1:
            raise ValueError("plot_gali takes a single-orbit result; index the batch first")
        line, = ax.loglog(result.t, g, label=f"GALI$_{{{k}}}$")
        if guide and n is not None and k > n and g[-1] > 0:
            _guide(ax, result.t, g[-1], -2.0 * (k - n), color=line.get_color())
    ax.set_xlabel("t")
    ax.set_ylabel("GALI")
    ax.legend(fontsize=8)
    return ax


def plot_sali(result, ax=None):
    """SALI(t) on log-log axes."""
    ax = _axes(ax)
    ax.loglog(result.t, np.asarray(result.sali), label="SALI")
    ax.set_xlabel("t")
    ax.set_ylabel("SALI")
    ax.legend(fontsize=8)
    return ax
