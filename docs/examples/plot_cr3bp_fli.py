"""
An FLI map of the restricted three-body problem
===============================================

The fast Lyapunov indicator (Froeschlé, Lega & Gonczi 1997) of orbits of
the circular restricted three-body problem of the Sun and Jupiter
(μ = 0.000954), started on the section y = 0 with ẏ > 0 at Jacobi
constant C = 3.05, on a grid of (x, p_x). In the frame that rotates with
the primaries the Hamiltonian is a rotating frame's kinetic term plus the
gravitational potential, so varint's tangent map method integrates it with
the exact flow of the rotating frame and the kick of the potential
(:class:`varint.models.CR3BP`): regular orbits (FLI ≈ ln t) and the
chaotic layers of the mean-motion resonances (FLI growing like χ₁ t)
separate at a glance. Points where no real ẏ gives C (2Ω < C, beyond the
zero-velocity curve) are left blank.
"""

import matplotlib.pyplot as plt
import numpy as np

import varint
from varint.models import CR3BP

nx, ny, t_end = 120, 90, 1000.0
# sphinx_gallery_start_ignore
import os  # noqa: E402

if os.environ.get("VARINT_DOCS_QUICK"):
    nx, ny, t_end = 40, 30, 300.0
# sphinx_gallery_end_ignore

model = CR3BP(0.000954)
grid = model.section_grid(3.05, np.linspace(0.3, 0.85, nx), np.linspace(-0.3, 0.3, ny))
r = varint.chaos_map(model, grid, "fli", t_end=t_end, progress=False)
# The defaults decide the step and the stepper, whichever is priced cheaper
# from its compiled code: the logarithmic time transformation (steps that
# shorten near the primaries) or constant steps of SRKN14a (on the quick
# map of studies/map_steps.py, constant steps since their r⁻³ and r⁻⁵ are
# written with square roots instead of pow).
opts = r.provenance.method_options
step = (f"fictitious step h = {opts['h']:.3g} ({opts['time_transform']} time transformation)"
        if opts.get("time_transform") else f"τ = {r.provenance.tau:.3g}")
print(f"{len(grid)} orbits, scheme {opts['scheme']['name']}, {step}, largest Jacobi-constant error "
      f"{r.accuracy.energy_error.max():.1e}")

# %%
# ``result.plot()`` draws the FLI on the grid of (x, p_x).
ax = r.plot()
ax.set_xlabel("x")
ax.set_ylabel("p$_x$")
ax.set_title(f"FLI at t = {t_end:g}, Sun–Jupiter, C = 3.05")
plt.show()

# %%
# The forbidden region for this Jacobi constant: where 2Ω(x, y) < C, the
# body cannot be (the grid above lies in the Sun's allowed region).
xs, ys = np.meshgrid(np.linspace(-1.5, 1.5, 400), np.linspace(-1.5, 1.5, 400))
fig, ax = plt.subplots(figsize=(4.5, 4.2), layout="constrained")
ax.contourf(xs, ys, model.forbidden(xs, ys, 3.05), levels=[0.5, 1.5], colors=["0.6"])
ax.plot([-model.mu, 1 - model.mu], [0, 0], "k*")
ax.plot([0.3, 0.85], [0, 0], "r-", lw=3, label="the map's x range")
ax.set_aspect("equal")
ax.set_xlabel("x")
ax.set_ylabel("y")
ax.legend(loc="lower left", fontsize=8)
ax.set_title("forbidden region (grey), C = 3.05")
plt.show()
