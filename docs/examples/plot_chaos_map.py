"""
A chaos map of the Hénon–Heiles section
=======================================

The SALI of every orbit started on a grid of the section x = 0, p_x ≥ 0
at H = 0.125: regular orbits keep SALI away from zero, chaotic ones drive
it below 1e-8 exponentially fast (Skokos 2001). The map shows at a glance
what the surfaces of section show orbit by orbit: the islands around R1
and the chaotic sea of C1.

:func:`varint.chaos_map` runs the grid in chunks, each one compiled batch
parallel over its orbits; an orbit whose SALI has fallen below the
threshold stops at the next check time and costs nothing more. With
``checkpoint=DIR`` an interrupted map resumes; with ``client=`` (a Dask
client) the chunks run on a cluster, with bitwise the same values.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

n, t_end = 150, 1000.0
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    n, t_end = 50, 300.0
# sphinx_gallery_end_ignore

model = varint.models.HenonHeiles()
grid = varint.section_grid(model, 0.125,
                           np.linspace(-0.45, 0.7, n),    # y
                           np.linspace(-0.45, 0.45, n))   # p_y; p_x solved from H
r = varint.chaos_map(model, grid, "sali", t_end=t_end, tau=0.05, progress=False)
print(f"{len(grid)} orbits, {r.decided.mean():.0%} decided chaotic before t_end, "
      f"in {r.provenance.wall_time:.1f} s")

# %%
# ``result.plot()`` draws log₁₀ SALI on the grid (white: outside the
# energetically allowed region); the paper's two orbits are marked.
ax = r.plot()
for name, marker in (("R1", "o"), ("C1", "s")):
    x0 = varint.paper_orbit(name)[1]
    ax.plot(x0[1], x0[3], marker, mfc="none", mec="w", ms=8)
    ax.annotate(name, (x0[1], x0[3]), xytext=(6, 6), textcoords="offset points", color="w")
ax.set_title(f"SALI at t = {t_end:g} (or when it fell below 1e-8)")
plt.show()

# %%
# The same map as an xarray Dataset, on its grid (``pip install
# "varint[xarray]"``): dimensions (p1, q1) = (p_y, y).
ds = r.to_xarray()
print(ds.value.dims, ds.value.shape)
