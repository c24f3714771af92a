"""
The standard map: a SALI map of its phase space
================================================

The standard map p' = p + K sin x, x' = x + p' iterated with its own tangent
map. At K = 1.2 islands and a chaotic sea share the cylinder; SALI tells
them apart: it falls to 0 (below double round-off, black) on chaotic orbits
and stays away from 0 on tori. The axes are named after the map's own
variables. Below: X₁ against Chirikov's law ln(K/2) at strong kicks.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

n, t_end = 120, 2000
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    n, t_end = 50, 1000
# sphinx_gallery_end_ignore

sm = varint.models.StandardMap(1.2)
grid = varint.phase_grid(sm, np.linspace(0, 2 * np.pi, n), np.linspace(-np.pi, np.pi, n))
m = varint.chaos_map(sm, grid, "sali", t_end=t_end, threshold=None, progress=False)
print(f"{np.mean(m.values < 1e-8):.0%} of the orbits have SALI < 1e-8 at t = {t_end}")

fig, ax = plt.subplots(figsize=(6, 4.6), layout="constrained")
m.plot(ax=ax)
ax.set_title("standard map, K = 1.2")

# %%
# X₁ of one orbit at strong kicks against ln(K/2).
Ks = np.array([4.0, 6.0, 10.0, 20.0])
X1 = [varint.run(varint.models.StandardMap(K), [1.0, 0.5], "x1", 2e4).exponents[-1, 0]
      for K in Ks]
fig, ax = plt.subplots(figsize=(5, 3.4), layout="constrained")
ax.plot(Ks, X1, "o", label="$X_1$ at $t = 2 \\times 10^4$")
ax.plot(Ks, np.log(Ks / 2), "k--", lw=0.8, label=r"$\ln(K/2)$")
ax.set_xlabel("K")
ax.set_ylabel("$X_1$")
ax.legend(fontsize=8)
plt.show()
