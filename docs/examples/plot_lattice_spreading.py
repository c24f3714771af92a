"""
Spreading and chaos of a disordered lattice
===========================================

A packet of energy on a disordered Klein–Gordon chain (Flach, Krimer &
Skokos 2009): one run of the ``"dvd"`` indicator gives both laws — the
packet's second moment m₂ and participation number P as it spreads, and
the finite-time maximum Lyapunov exponent Λ(t) = X₁(t) with the deviation
vector distribution (DVD), whose peaks show where the chaos is (Senyange,
Many Manda & Skokos 2018). ``r.plot()`` draws them as log–log panels.
"""

import matplotlib.pyplot as plt

import varint

sites, t_end = 256, 1e4
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    sites, t_end = 128, 1e3
# sphinx_gallery_end_ignore

kg = varint.models.DisorderedKG(sites, W=4.0, seed=1)
x0 = kg.initial_block(21, 0.02)            # 21 central sites, energy density 0.02
r = varint.run(kg, x0, "dvd", t_end, 0.2, scheme="ABA864", profiles=True)
print(r.summary())
print(f"m2 {r['m2'][0]:.3g} -> {r['m2'][-1]:.3g}, P {r['participation'][-1]:.3g}, "
      f"Lambda {r['x1'][-1]:.3g}")

# %%
# The panels: Λ with the regular-motion law t⁻¹, and m₂ and P of the packet
# and of the DVD.
axes = r.plot()
axes[0].figure.set_size_inches(10, 3.3)

# %%
# The energy distribution z_l and the DVD ξ_l over the sites at the end of
# the run (``profiles=True`` keeps them at every output time).
fig, ax = plt.subplots(figsize=(7, 3), layout="constrained")
ax.semilogy(r.values["profile"][-1], label="energy $z_l$")
ax.semilogy(r.values["dvd"][-1], label=r"DVD $\xi_l$")
ax.set_xlabel("site l")
ax.set_ylim(1e-12, 1)
ax.legend(fontsize=8)
plt.show()
