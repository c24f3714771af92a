r"""
Lyapunov spectra of a regular and a chaotic orbit
=================================================

The finite-time Lyapunov exponents :math:`X_1(t), …, X_4(t)` of the paper's regular
orbit R1 and chaotic orbit C1 (Hénon–Heiles, H = 0.125), computed by the
tangent map method with the paper's scheme SBAB2C at τ = 0.05 — Skokos &
Gerlach (2010), Figs. 2 and 5.

On the torus of R1 the deviation vectors grow linearly, so :math:`X_1` falls as
:math:`\ln t / t` (the dashed 1/t guide, paper eq. 12). On C1, :math:`X_1` tends to the
maximal Lyapunov exponent :math:`χ_1 ≈ 0.045`. For an autonomous Hamiltonian the
spectrum comes in opposite pairs, :math:`X_i + X_{5-i} → 0` (eq. 13).
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

t_end = 1e6
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_end = 2e4
# sphinx_gallery_end_ignore

# %%
# Both orbits in one call: ``x0`` of shape (2, 4) runs them in parallel,
# and the result gains a leading orbit axis.
model, r1 = varint.paper_orbit("R1")
_, c1 = varint.paper_orbit("C1")
r = varint.lyapunov_spectrum(model, np.array([r1, c1]), t_end, tau=0.05, scheme="SBAB2C")
print(r.summary())
print("X_i at t_end, R1:", r.exponents[0, -1])
print("X_i at t_end, C1:", r.exponents[1, -1])

# %%
# ``result.plot(orbit=m)`` draws one orbit in the paper's style: the
# positive half of the spectrum on log-log axes, with the 1/t law of
# regular orbits.
fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained", sharey=True)
r.plot(orbit=0, ax=axes[0])
axes[0].set_title("R1: regular, X$_i$ ∝ ln t / t")
r.plot(orbit=1, ax=axes[1], guide=False)
axes[1].axhline(0.045, color="k", ls=":", lw=0.8, label=r"$\chi_1 \approx 0.045$")
axes[1].legend(fontsize=8)
axes[1].set_title("C1: chaotic, X$_1$ → χ$_1$")

# %%
# The pair sums ``|X_1 + X_4|`` measure how well the integration keeps the
# symplectic structure of the tangent dynamics: they fall as 1/t. (With
# the full spectrum, X₁ + X₂ + X₃ + X₄ = 0 to round-off — the tangent map
# preserves volume — so ``|X_2 + X_3|`` is the same curve.)
sums = r.pair_sums()
fig, ax = plt.subplots(figsize=(5, 3.6), layout="constrained")
for m, name in enumerate(("R1", "C1")):
    ax.loglog(r.t, sums[m, :, 0], label=f"{name}: |X$_1$ + X$_4$|")
ax.loglog(r.t, 1 / r.t, "k--", lw=0.8, label="1/t")
ax.set_xlabel("t")
ax.set_ylabel("pair sum")
ax.legend(fontsize=8)
plt.show()
