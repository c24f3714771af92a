"""
GALI of orbits in a rotating barred galaxy
==========================================

The generalized alignment index GALI_k (Skokos, Bountis & Antonopoulos
2007) of two orbits of the barred-galaxy model of Skokos, Patsis &
Athanassoula (2002): a Ferrers bar, a Miyamoto–Nagai disc and a Plummer
bulge, seen from the frame rotating with the bar
(:class:`varint.models.RotatingBar`). For a regular orbit on a
3-dimensional torus GALI_2 and GALI_3 stay finite while GALI_4 … GALI_6
fall as powers of t; for a chaotic orbit every GALI_k falls exponentially,
GALI_k ∝ exp(−Σ(χ₁ − χ_j) t). This is how Manos & Athanassoula (2011)
charted regular and chaotic orbits in barred galaxies.
"""

import matplotlib.pyplot as plt

import varint
from varint.models import bar_orbit

t_end = 2000.0
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_end = 500.0
# sphinx_gallery_end_ignore

fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained", sharey=True)
for ax, name in zip(axes, ("regular", "chaotic"), strict=True):
    model, x0 = bar_orbit(name)
    r = varint.gali(model, x0, t_end, k=(2, 3, 4, 6), tau=0.05)
    for k, values in r.gali.items():
        ax.loglog(r.t, values, label=f"GALI$_{k}$")
    ax.set_title(f"{name} orbit, E$_J$ = {model.energy(x0):.2f}")
    ax.set_xlabel("t")
axes[0].set_ylabel("GALI$_k$")
axes[0].legend(fontsize=8)
plt.show()
