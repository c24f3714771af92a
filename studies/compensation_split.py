"""How much of the orbit-plus-tangent error is round-off, at each
compensation level (issue 27: C2 at 1e-10).

Two runs of one scheme at one τ differ only in their rounding, so the
distance of a run from the same run fully compensated (``compensated=True``)
is its round-off error alone, truncation cancelled, with no reference
needed (the fully compensated run's own round-off is at the floor of
``studies/compensated_floor.py``, 1e-14 to 1e-12, below what is measured
here). Measured: the relative Frobenius distance of the tangent map
(2N unit vectors, ``deviations=np.eye(2N)``) and of the state at t_end,
for ``compensated=False``, ``"step"`` and ``"orbit"``, over a ladder of
steps: a round-off error that does not fall when τ halves is a floor, one
that grows is a sum of per-step roundings.

Case: the paper's R1 and C2, SRKN14a, t_end = 1e3 (``--quick``: 1e2).

Usage: ``python studies/compensation_split.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

import varint  # noqa: E402
from studies.common import parse_args, save_csv  # noqa: E402

LEVELS = (False, "step", "orbit")
TAUS = (1 / 16, 1 / 32, 1 / 64, 1 / 128)
SCHEME = "SRKN14a"
COLUMNS = ("orbit", "scheme", "tau", "level", "t_end", "roundoff_state", "roundoff_tangent")


def run(orbit, tau, level, t_end):
    """The state and tangent map at t_end of one run."""
    model, x0 = varint.paper_orbit(orbit)
    opts = {"compensated": level} if level else {}
    r = varint.integrate(model, x0, t_end, tau=tau, method="tm", scheme=SCHEME,
                         deviations=np.eye(model.dim), progress=False, **opts)
    return np.asarray(r.state).reshape(-1), np.asarray(r.deviations)


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv)
    t_end = 1e2 if args.quick else 1e3
    rows = []
    for orbit in ("R1", "C2"):
        for tau in TAUS:
            x_ref, w_ref = run(orbit, tau, True, t_end)
            for level in LEVELS:
                x, w = run(orbit, tau, level, t_end)
                rows.append({"orbit": orbit, "scheme": SCHEME, "tau": tau,
                             "level": {False: "plain", "step": "+cs", "orbit": "+co"}[level],
                             "t_end": t_end,
                             "roundoff_state": float(np.linalg.norm(x - x_ref)
                                                     / np.linalg.norm(x_ref)),
                             "roundoff_tangent": float(np.linalg.norm(w - w_ref)
                                                       / np.linalg.norm(w_ref))})
                r = rows[-1]
                print(f"{orbit} tau=1/{round(1 / tau):<4d} {r['level']:>5s}  state "
                      f"{r['roundoff_state']:.2e}  tangent {r['roundoff_tangent']:.2e}",
                      flush=True)
    print(save_csv(args.out, "compensation_split", rows, COLUMNS))
    return {"rows": rows}


if __name__ == "__main__":
    main()
