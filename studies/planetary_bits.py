"""Bitwise fingerprints of planetary runs: one per kind of kernel the part
stepper of :class:`varint.models.Planetary` compiles — the one-orbit
stepper (MEGNO, one vector; the exact tangent map, renorm "none", three
vectors), the SIMD-lane block (eight orbits, one of them eccentric enough
that its Kepler drift leaves the lanes for the one-orbit flow), the WHT
corrector at outputs, a close encounter, and democratic heliocentric
coordinates (three parts). Run with two trees (``PYTHONPATH``) on fresh
caches and compare the printed hashes: a change that should not change a
bit changes none of them.

Usage: ``python studies/planetary_bits.py [--only PREFIX …] [--out DIR]``
(stored as ``planetary_bits.json``).
"""

from __future__ import annotations

import hashlib
import warnings

import numpy as np

import varint
from varint.models import Planetary

try:
    from common import parse_args, save_json
except ImportError:  # imported as studies.planetary_bits
    from .common import parse_args, save_json

WH4 = varint.get_scheme("SABA1").repeated(4)


def digest(result):
    """A hash of every array a result holds that a run computes."""
    h = hashlib.sha256()
    for name in ("state", "deviations", "megno", "values", "status", "t_stop", "energy_error"):
        value = getattr(result, name, None)
        if value is not None:
            h.update(name.encode())
            h.update(np.ascontiguousarray(value).tobytes())
    return h.hexdigest()[:16]


def cases():
    """(label, function making a result) of every case."""
    model = Planetary([1.0, 1e-3, 3e-4])
    x0 = model.from_elements([dict(a=1.0, e=0.05), dict(a=1.6, e=0.1, M=2.0, inc=0.1)])
    X = np.stack([model.from_elements([dict(a=1.0, e=0.05 if m != 5 else 0.95, M=0.3 * m),
                                       dict(a=1.6 + 0.02 * m, e=0.1, M=2.0, inc=0.1)])
                  for m in range(8)])
    close = Planetary([1.0, 1e-3, 3e-4], close_encounter=3.0)
    Xc = np.stack([close.from_elements(e) for e in (
        [dict(a=1.0, e=0.0), dict(a=1.02, e=0.0, M=0.15)],
        [dict(a=1.0, e=0.0), dict(a=3.0, e=0.0, M=2.0)])])
    dem = Planetary([1.0, 1e-3, 3e-4], coordinates="democratic")
    xd = dem.from_cartesian(*model.to_cartesian(x0))
    return [
        ("megno/one-orbit", lambda: varint.megno(model, x0, 50.0, tau=0.5, t_out=5,
                                                 parallel=False)),
        ("integrate/none-k3", lambda: varint.integrate(model, x0, 20.0, tau=0.25, t_out=2,
                                                       deviations=np.eye(12)[:, :3],
                                                       scheme=WH4)),
        ("megno/lanes", lambda: varint.megno(model, X, 50.0, tau=0.5, t_out=5,
                                             parallel=False, errors="flag")),
        ("megno/corrector", lambda: varint.megno(model, x0, 50.0, tau=0.5, t_out=5,
                                                 corrector=3, parallel=False)),
        ("megno/close-encounter", lambda: varint.megno(close, Xc, 20.0, tau=0.05, t_out=4,
                                                       errors="flag", parallel=False,
                                                       lanes=False)),
        ("megno/democratic", lambda: varint.megno(dem, xd, 20.0, tau=0.25, t_out=2,
                                                  parallel=False)),
    ]


def _extra(parser):
    parser.add_argument("--only", nargs="*", default=None, metavar="PREFIX",
                        help="run only the cases whose label starts with one of these")


def main(argv=None):
    args = parse_args(__doc__.splitlines()[0], argv, extra=_extra)
    table = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for label, run in cases():
            if args.only and not label.startswith(tuple(args.only)):
                continue
            table[label] = digest(run())
            print(f"{label:24s} {table[label]}", flush=True)
    save_json(args.out, "planetary_bits", {"digests": table})


if __name__ == "__main__":
    main()
