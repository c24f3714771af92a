"""
A MEGNO stability map of a two-planet system
============================================

The stability map of REBOUND's tutorial "Stability map with MEGNO and
WHFast": the Sun, Jupiter (a = 5.204, e = 0.048) and a planet of Saturn's
mass whose semi-major axis a and eccentricity e span [7, 10] × [0, 0.5],
over 500 years. Orbits near the mean-motion resonances with Jupiter (2:1 at
a ≈ 8.26, 5:2 at a ≈ 9.58, where Saturn is) and those whose eccentricity
brings them near Jupiter are chaotic: the running mean of MEGNO, Ȳ, grows
there instead of settling at 2 (Cincotta & Simó 2000; Goździewski et al.
2001 for MEGNO maps of planetary systems).

The map runs the Wisdom–Holman map in Jacobi coordinates with its tangent
map (``method="tm"``, :doc:`/user_guide/planetary`), ten steps of dt = 1
(Jupiter's period / 75) per renormalisation interval, parallel over the
grid; an orbit is frozen once Ȳ > 4 at a check time, once its planets
come within three mutual Hill radii (``close_encounter=3.0``: the map does
not resolve encounters), or once it escapes beyond 20 AU. The run's warning
counts the orbits stopped by encounters and escapes: they are the map's
unstable orbits, drawn as the most chaotic.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint

n_grid, years = 80, 500
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    n_grid = 16
# sphinx_gallery_end_ignore

model = varint.models.Planetary([1.0, 0.000954, 0.000285],       # G = 1, AU, solar masses
                                close_encounter=3.0)
jupiter = dict(a=5.204, e=0.048, omega=0.257, M=0.600)
outer = dict(a=9.0, e=0.0, omega=1.616, M=0.871)
grid = varint.element_grid(model, [jupiter, outer], planet=2,
                           u=np.linspace(7.0, 10.0, n_grid), v=np.linspace(0.0, 0.5, n_grid),
                           axes=("a", "e"))
r = varint.chaos_map(model, grid, "megno", t_end=years * 2 * np.pi, tau=10.0,
                     scheme=varint.get_scheme("SABA1").repeated(10), threshold=4.0,
                     escape_radius=20.0, progress=False)
chaotic = np.mean(~(r.values <= 4.0))
print(f"{len(grid)} orbits over {years} years: {chaotic:.0%} chaotic, met or escaped "
      f"({int(r.decided.sum())} stopped early), {r.provenance.wall_time:.1f} s")

# %%
# Ȳ clipped to [1.8, 4] as in REBOUND's tutorial; orbits stopped by an
# encounter or an escape (NaN) are drawn as the most chaotic.
fig, ax = plt.subplots(figsize=(6.4, 4.4), layout="constrained")
image = np.clip(np.nan_to_num(r.image(), nan=4.0), 1.8, 4.0)
art = ax.imshow(image, origin="lower", extent=[7.0, 10.0, 0.0, 0.5], aspect="auto",
                cmap="RdYlGn_r", interpolation="nearest")
for ratio, label in ((2.0, "2:1"), (2.5, "5:2")):
    a_res = jupiter["a"] * ratio ** (2 / 3)
    ax.axvline(a_res, color="k", lw=0.6, ls=":")
    ax.text(a_res, 0.48, label, ha="center", va="top", fontsize=8)
ax.plot(9.537, 0.054, "k*", ms=9, label="Saturn")
ax.set_xlabel("$a$ of the outer planet (AU)")
ax.set_ylabel("$e$ of the outer planet")
ax.legend(loc="lower right", fontsize=8)
fig.colorbar(art, ax=ax, label=r"MEGNO $\bar Y$")
plt.show()
