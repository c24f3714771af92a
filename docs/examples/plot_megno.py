"""
MEGNO, FLI and OFLI
===================

The mean exponential growth of nearby orbits (MEGNO, Cincotta & Simó
2000) and the fast Lyapunov indicators FLI and OFLI of R1 and C1, from one
deviation vector, accumulated at every step by the compiled stepper.

On a quasi-periodic orbit the running mean Ȳ of MEGNO tends to 2; on a
chaotic orbit it grows as χ₁ t / 2. FLI grows as ln t on a torus and as
χ₁ t in chaos.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

t_end = 1e4
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_end = 2e3
# sphinx_gallery_end_ignore

model, r1 = varint.paper_orbit("R1")
_, c1 = varint.paper_orbit("C1")
m = varint.megno(model, np.array([r1, c1]), t_end, tau=0.05, t_out=400)
print(f"mean MEGNO at t_end: R1 {m.mean_megno[0, -1]:.3f}, C1 {m.mean_megno[1, -1]:.1f}")
print(f"C1: 2 Ȳ / t = {2 * m.mean_megno[1, -1] / m.t[-1]:.4f} (≈ χ₁ ≈ 0.045)")

# %%
fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
m.plot(orbit=0, ax=axes[0])
axes[0].set_title("R1: Ȳ → 2")
axes[1].plot(m.t, m.mean_megno[1], label=r"C1: $\bar Y$")
axes[1].plot(m.t, 0.045 * m.t / 2, "k--", lw=0.8, label=r"$\chi_1 t / 2$")
axes[1].set_xlabel("t")
axes[1].set_ylabel("MEGNO")
axes[1].legend(fontsize=8)
axes[1].set_title("C1: Ȳ ≈ χ₁ t / 2")

# %%
# FLI and OFLI of both orbits (``which="fli"``).
fig, ax = plt.subplots(figsize=(5, 3.6), layout="constrained")
for i, name in enumerate(("R1", "C1")):
    ax.semilogx(m.t, m.fli[i], label=f"{name}: FLI")
    ax.semilogx(m.t, m.ofli[i], "--", label=f"{name}: OFLI")
ax.set_xlabel("t")
ax.set_ylabel("ln ‖w‖")
ax.legend(fontsize=8)
plt.show()
