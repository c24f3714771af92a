r"""
GALIs: power laws on a torus, exponential decay in chaos
========================================================

The generalised alignment indices GALI₂, GALI₃ and GALI₄ of R1 and C1 —
Skokos & Gerlach (2010), Figs. 4 and 5.

On an N-torus GALIₖ stays roughly constant for k ≤ N and falls as
:math:`t^{-2(k-N)}` for k > N (paper eq. 17): for the 2-torus of R1,
GALI₂ ≈ const, GALI₃ ∝ :math:`t^{-2}`, GALI₄ ∝ :math:`t^{-4}` (dashed
guides). On a chaotic orbit every GALIₖ falls exponentially,
:math:`\mathrm{GALI}_k ∝ e^{-[(χ_1-χ_2) + … + (χ_1-χ_k)]\,t}` (eq. 16),
until it reaches the round-off floor ~1e-16.
"""

import matplotlib.pyplot as plt

import varint

t_regular = 1e5
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_regular = 1e4
# sphinx_gallery_end_ignore

model, r1 = varint.paper_orbit("R1")
_, c1 = varint.paper_orbit("C1")
g_r1 = varint.gali(model, r1, t_regular, tau=0.05, k=(2, 3, 4))
# C1's GALIs reach round-off by t ≈ 200: running longer only measures noise.
g_c1 = varint.gali(model, c1, 300.0, tau=0.05, k=(2, 3, 4), t_out=300)

# %%
fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
g_r1.plot(ax=axes[0])
axes[0].set_title("R1: GALI$_2$ const, GALI$_3$ ∝ t$^{-2}$, GALI$_4$ ∝ t$^{-4}$")
for k, values in sorted(g_c1.gali.items()):
    axes[1].semilogy(g_c1.t, values, label=f"GALI$_{k}$")
axes[1].set_xlabel("t")
axes[1].set_ylabel("GALI")
axes[1].legend(fontsize=8)
axes[1].set_title("C1: exponential decay (linear time axis)")
plt.show()

# %%
# The slopes of the regular orbit's GALIs over the last decade, against
# the laws 0, −2 and −4:
import numpy as np  # noqa: E402

last = g_r1.t >= g_r1.t[-1] / 10
for k in (2, 3, 4):
    slope = np.polyfit(np.log(g_r1.t[last]), np.log(g_r1.gali[k][last]), 1)[0]
    print(f"GALI_{k}: slope {slope:+.2f}")
