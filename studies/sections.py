"""Surfaces of section of Hénon–Heiles at H = 0.125: the paper's Figs. 1 and 6,
and a SALI map of the same section.

1. Fig. 1: the section x = 0, p_x ≥ 0 with R1 (five closed curves around the
   right large island), C1 (scattered over the chaotic sea) and other orbits
   in gray. Checked: R1's crossings form five separate curves (single-linkage
   clusters), C1's cover a large part of the section, every crossing lies on
   x = 0 to round-off and conserves the energy to the scheme's accuracy.
2. Fig. 6: the weakly chaotic C2, confined for long times to a thin layer
   around a chain of small islands; shown zoomed on the island it starts at.
   Checked: at an equal number of crossings C2 covers a small fraction of
   the area C1 covers.
3. A SALI chaos map of the section (varint.chaos_map), on which R1's island
   is regular and C1's sea chaotic.

Run: ``python studies/sections.py [--quick]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from studies import claims as rules  # noqa: E402
from studies.common import Claims, Stopwatch, figure, parse_args, save_json  # noqa: E402
from varint.models import HenonHeiles  # noqa: E402
from varint.plotting import plot_chaos_map, plot_section  # noqa: E402

ENERGY = 0.125
#: Section coordinates (y, p_y) are state indices 1 and 3.
AXES = [1, 3]
#: Cells of the coverage grid (y, p_y): as coarse as ~1500 crossings need
#: to fill the chaotic sea.
CELL = 0.025
_U = np.arange(-0.45, 0.7 + 1e-9, CELL)
_V = np.arange(-0.5, 0.5 + 1e-9, CELL)


def gray_orbits(model):
    """Initial conditions of the gray background orbits: along p_y = 0 and
    a few off it, on the section at H = 0.125."""
    ys = list(np.linspace(-0.4, 0.65, 15)) + [0.1, 0.2, 0.3]
    pys = [0.0] * 15 + [0.2, 0.25, -0.2]
    out = []
    for y, py in zip(ys, pys, strict=True):
        try:
            out.append(varint.solve_momentum(model, [0.0, y], [0.0, py], ENERGY))
        except ValueError:  # outside the allowed region
            continue
    return np.array(out)


def crossings(res, i):
    """The (y, p_y) of orbit i's crossings."""
    return res.points[i, :res.n_points[i]][:, AXES]


def n_curves(points, distance=0.02):
    """Number of separate curves: single-linkage clusters whose points lie
    closer than ``distance`` to a neighbour."""
    return int(fcluster(linkage(points, "single"), distance, "distance").max())


def coverage(points, mask):
    """Fraction of the allowed cells of the (y, p_y) grid that ``points`` visit."""
    iu = np.clip(np.round((points[:, 0] - _U[0]) / CELL).astype(int), 0, len(_U) - 1)
    iv = np.clip(np.round((points[:, 1] - _V[0]) / CELL).astype(int), 0, len(_V) - 1)
    return len(set(zip(iu.tolist(), iv.tolist(), strict=True))) / int(mask.sum())


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    quick = args.quick
    claims = Claims("sections", args.out)
    model = HenonHeiles()
    orbits = {name: varint.paper_orbit(name)[1] for name in ("R1", "C1", "C2")}
    t_fig1 = 1e4 if quick else 5e4
    t_gray = 2e3 if quick else 5e4
    t_c2 = 1e4 if quick else 1e6
    tau, scheme = 0.05, "ABA864"

    with Stopwatch() as sw1:
        main_orbits = varint.surface_of_section(model, np.array([orbits["R1"], orbits["C1"]]),
                                                t_fig1, tau=tau, scheme=scheme)
        gray = varint.surface_of_section(model, gray_orbits(model), t_gray, tau=tau,
                                         scheme=scheme)
    with Stopwatch() as sw2:
        c2 = varint.surface_of_section(model, orbits["C2"], t_c2, tau=tau, scheme=scheme)
    allowed = varint.section_grid(model, ENERGY, _U, _V).mask

    r1, c1 = crossings(main_orbits, 0), crossings(main_orbits, 1)
    c2_points = c2.points[:c2.n_points][:, AXES]
    curves = n_curves(r1)
    n_eq = min(len(r1), len(c1), len(c2_points))
    cov = {"R1": coverage(r1[:n_eq], allowed), "C1": coverage(c1[:n_eq], allowed),
           "C2": coverage(c2_points[:n_eq], allowed)}
    cov_c2_all = coverage(c2_points, allowed)
    all_x = np.concatenate([main_orbits.points[..., 0].ravel(), gray.points[..., 0].ravel(),
                            c2.points[:, 0]])
    all_e = np.concatenate([main_orbits.energy_error.ravel(), gray.energy_error.ravel(),
                            c2.energy_error])
    max_x, max_e = float(np.nanmax(np.abs(all_x))), float(np.nanmax(all_e))
    n_cross = int(main_orbits.n_points.sum() + gray.n_points.sum() + c2.n_points)

    claims.add("Fig. 1: R1's crossings form five closed curves (islands) on x = 0, p_x ≥ 0",
               "5 closed curves", f"{curves} separate curves ({len(r1)} crossings to "
               f"t = {t_fig1:g}; single-linkage clusters at distance 0.02)", curves == 5,
               figure="sections_fig1.png")
    # Scattered: a fair part of the section, and above the regular R1's
    # coverage by the rule for "A above B".
    spread = rules.above(cov["C1"], cov["R1"], "C1/R1 ")
    claims.add("Fig. 1: C1's crossings are scattered over the chaotic sea",
               "randomly scattered points",
               f"C1 visits {cov['C1']:.0%} of the section's {CELL:g} × {CELL:g} cells, R1 "
               f"{cov['R1']:.1%} (at {n_eq} crossings each)",
               cov["C1"] > 0.2 and spread.holds, figure="sections_fig1.png", rules=[spread])
    claims.add("Crossings are points of the numerical orbit on the section to round-off",
               "—", f"max |x| = {max_x:.1e} and max relative energy error {max_e:.1e} over "
               f"{n_cross} crossings ({scheme}, τ = {tau:g}, Newton on the step length)",
               max_x < 1e-12 and max_e < 1e-8, source="own")
    thin = rules.above(cov["C1"], cov["C2"])
    claims.add("Fig. 6: the weakly chaotic C2 stays in a thin layer around small islands",
               "thin region at the borders of a small island",
               f"C2 visits {cov['C2']:.1%} of the cells at {n_eq} crossings (C1: "
               f"{cov['C1']:.0%}); {cov_c2_all:.1%} with all {len(c2_points)} crossings to "
               f"t = {t_c2:g}; confined: C1/C2 {thin.value:.2g}",
               thin.holds, figure="sections_fig6.png", rules=[thin])

    n_grid = 40 if quick else 120
    t_map = 500.0 if quick else 1e3
    grid = varint.section_grid(model, ENERGY, np.linspace(-0.45, 0.7, n_grid),
                               np.linspace(-0.45, 0.45, n_grid))
    with Stopwatch() as sw3:
        smap = varint.chaos_map(model, grid, "sali", t_end=t_map, tau=0.05, progress=False)

    def at(name, around=0):
        """SALI at the grid point nearest the orbit's start, or the median
        over the (2·around + 1)² points around it."""
        y, py = orbits[name][1], orbits[name][3]
        i, j = np.argmin(np.abs(grid.v - py)), np.argmin(np.abs(grid.u - y))
        block = smap.image()[max(i - around, 0):i + around + 1, max(j - around, 0):j + around + 1]
        return float(np.nanmedian(block))

    chaotic = float(np.mean(smap.values < 1e-8))
    claims.add("SALI map of the section: R1's island regular, C1's sea chaotic",
               "R1 regular, C1 chaotic (Sect. VI.A)",
               f"SALI at the grid point nearest R1: {at('R1'):.2g} (R1's island is small); "
               f"median of the 3 × 3 points around C1: {at('C1', 1):.2g}; {chaotic:.0%} of "
               f"{len(smap.values)} orbits below 1e-8 at t = {t_map:g} ({sw3.seconds:.1f} s, "
               f"{int(smap.decided.sum())} stopped early)",
               at("R1") > 1e-2 and at("C1", 1) < 1e-8, figure="sections_sali_map.png",
               source="own")
    claims.save()

    path, plt = figure(args.out, "sections_fig1")
    fig, ax = plt.subplots(figsize=(6, 5), layout="constrained")
    plot_section(gray, ax, color="0.7", size=0.5)
    plot_section(main_orbits, ax, color="k", size=0.8)
    ax.set_title(f"Hénon–Heiles, H = {ENERGY}: x = 0, $p_x$ ≥ 0 (Fig. 1)")
    fig.savefig(path, dpi=130)
    plt.close(fig)

    # Fig. 6: the island C2 starts next to, with a margin.
    labels = fcluster(linkage(c2_points[:min(len(c2_points), 4000)], "single"), 0.04,
                      "distance")
    own = c2_points[:len(labels)][labels == labels[0]]
    lo, hi = own.min(axis=0), own.max(axis=0)
    pad = 0.15 * (hi - lo)
    path, plt = figure(args.out, "sections_fig6")
    fig, ax = plt.subplots(figsize=(5, 4.5), layout="constrained")
    plot_section(c2, ax, color="k", size=0.6)
    ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
    ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.set_title(f"C2 to t = {t_c2:g} (part of the section, Fig. 6)")
    fig.savefig(path, dpi=130)
    plt.close(fig)

    path, plt = figure(args.out, "sections_sali_map")
    fig, ax = plt.subplots(figsize=(6, 4.8), layout="constrained")
    plot_chaos_map(smap, ax)
    for name, marker in (("R1", "o"), ("C1", "s")):
        ax.plot(orbits[name][1], orbits[name][3], marker, mfc="none", mec="r", label=name)
    ax.legend(loc="upper right")
    ax.set_title(f"SALI at t = {t_map:g}, {n_grid}×{n_grid} grid")
    fig.savefig(path, dpi=130)
    plt.close(fig)

    result = {"r1_curves": curves, "coverage": cov, "coverage_c2_all": cov_c2_all,
              "max_abs_x": max_x, "max_energy_error": max_e, "crossings": n_cross,
              "sali_r1": at("R1"), "sali_c1": at("C1", 1), "chaotic_fraction": chaotic,
              "seconds": {"fig1": sw1.seconds, "c2": sw2.seconds, "map": sw3.seconds}}
    save_json(args.out, "sections", result)
    result["claims"] = claims.items
    return result


if __name__ == "__main__":
    main()
    sys.exit(0)
