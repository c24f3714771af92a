"""
Where the TDH methods fail on a regular orbit
=============================================

The paper's TDH methods integrate the tangent dynamics Hamiltonian along
an orbit known only at the grid times. Their tangent error is of order 1
(TDHcc, TDHes) or 4 (TDHeps), yet on the regular orbit R1 they go wrong in
a way the order hides: after some time :math:`X_1` stops falling as :math:`1/t` and levels
off at a positive value — the false verdict "chaotic" of Skokos & Gerlach
(2010), Fig. 2. The TM method keeps :math:`X_1 ∝ 1/t`.

:func:`varint.departure` runs the method and a TM reference (ABA864, same
τ and initial vectors) and says when :math:`X_1` and the GALIs depart, and where
:math:`X_1` levels off.
"""

import matplotlib.pyplot as plt

import varint

t_end = 5e4
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_end = 2e4
# sphinx_gallery_end_ignore

model, r1 = varint.paper_orbit("R1")
d = varint.departure(model, r1, "tdhcc", tau=0.05, t_end=t_end)
print(f"X1 departs at t = {d.t_x1:.3g} and levels off at {d.level:.2g} "
      "(the paper's Table I: 9.4e-4)")
print("GALI_k depart at", {k: round(t) for k, t in d.t_gali.items() if t is not None})

# %%
# X₁ of both runs (absolute values: at early times X₁ may be negative),
# with the departure time and the level TDHcc settles to.
fig, ax = plt.subplots(figsize=(5.5, 3.8), layout="constrained")
ax.loglog(d.t, abs(d.x1_reference), label="TM (ABA864)")
ax.loglog(d.t, abs(d.x1), label="TDHcc")
ax.axvline(d.t_x1, color="k", ls=":", lw=0.8, label="departure")
if d.level is not None:
    ax.hlines(d.level, d.t_x1, d.t[-1], color="tab:orange", ls="--", lw=0.8, label="level")
ax.set_xlabel("t")
ax.set_ylabel("|X$_1$|")
ax.legend(fontsize=8)
ax.set_title("R1, τ = 0.05")
plt.show()
