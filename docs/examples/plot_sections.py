"""
Surfaces of section of R1 and C1
================================

The crossings of the paper's orbits with the section x = 0, p_x ≥ 0 of the
Hénon–Heiles system — Skokos & Gerlach (2010), Fig. 1: R1 draws the five
islands of a regular orbit, C1 fills the chaotic sea.

:func:`varint.surface_of_section` integrates with a splitting scheme
(ABA864 by default) and finds each crossing by re-integrating the step that
crossed the plane with a shorter step, solved by Newton's method: every
point lies on the plane to round-off and belongs to the numerical orbit.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

t_end = 2e4
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    t_end = 3e3
# sphinx_gallery_end_ignore

model, r1 = varint.paper_orbit("R1")
_, c1 = varint.paper_orbit("C1")
s = varint.surface_of_section(model, np.array([r1, c1]), t_end, tau=0.01)
print("crossings:", s.n_points, " largest energy error:", np.nanmax(s.energy_error))

# %%
# ``points`` holds the states at the crossings, NaN-padded per orbit; the
# section's coordinates are (y, p_y) = state indices 1 and 3.
fig, ax = plt.subplots(figsize=(5.5, 4.5), layout="constrained")
for i, name, color, size in ((1, "C1", "tab:red", 1.0), (0, "R1", "k", 1.5)):
    pts = s.points[i, : s.n_points[i]]
    ax.scatter(pts[:, 1], pts[:, 3], s=size, c=color, linewidths=0, label=name)
ax.set_xlabel("y")
ax.set_ylabel("$p_y$")
ax.legend(markerscale=5, fontsize=8)
ax.set_title("x = 0, $p_x$ ≥ 0, H = 0.125")
plt.show()
