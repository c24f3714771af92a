"""
Local Lyapunov exponents and their distribution
===============================================

Local (finite-time) Lyapunov exponents over windows of length Δ — the
"stretching numbers" of Voglis & Contopoulos (1994) — registered as the
indicator ``"local_exponents"``. The whole indicator is one file of
varint (:mod:`varint.indicators.local_exponents`); :func:`varint.run`
computes it with every method.

A regular orbit's local exponents scatter narrowly about a small value;
a chaotic orbit's scatter widely about χ₁.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

t_end = 1e5
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_end = 2e4
# sphinx_gallery_end_ignore

model, r1 = varint.paper_orbit("R1")
_, c1 = varint.paper_orbit("C1")
r = varint.run(model, np.array([r1, c1]), "local_exponents", t_end, tau=0.05, window=10.0)
print("windows:", r.windows[:, -1, 0], " mean local exponent:", r.mean[:, -1, 0])

# %%
fig, ax = plt.subplots(figsize=(5.5, 3.8), layout="constrained")
for orbit, name in enumerate(("R1", "C1")):
    counts, edges = r.distribution(bins=80, orbit=orbit)
    ax.stairs(counts, edges, label=name)
ax.axvline(0.045, color="k", ls=":", lw=0.8, label=r"$\chi_1$ of C1")
ax.set_xlabel("local exponent over Δ = 10")
ax.set_ylabel("density")
ax.legend(fontsize=8)
plt.show()
