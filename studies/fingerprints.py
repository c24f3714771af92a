"""Bitwise fingerprints of varint's results, to prove that a refactoring
changed no bit.

Every method × scheme × model combination that varint runs (the TM method's
generated and generic steppers on every two-part scheme, the part stepper on
every lattice and k-part scheme, maps, the TDH methods, the baselines, the
two-particle method, every indicator, batches serial and parallel,
time-dependent potentials, the automatic step, chaos maps, ensembles and
sections) is run briefly, and the SHA-256 of every number in its result
(the arrays and scalars of the result, never its wall time or versions) is
stored. ``--check`` recomputes them and lists every case whose bits moved.

Bits depend on the machine (fused multiply–adds, SIMD width) and on the
versions of NumPy and numba, so a stored set is compared only on the machine
and versions that wrote it (both are recorded and printed: the CPU's model
name, LLVM's name of it, which numba compiles for, and whether NumPy sees
AVX-512). Two "AMD EPYC" CPUs, one with AVX-512 and one without, gave
different bits for 45 of 88 cases of the same code (stop 50).

Usage::

    python studies/fingerprints.py --write     # store studies/results/fingerprints.json
    python studies/fingerprints.py --check     # compare, exit status 1 on any change
    python studies/fingerprints.py --check --only tm/   # cases whose label starts so
    python studies/fingerprints.py --check --tiny-chunks # the same bits in tiny chunks
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
STORE = HERE / "results" / "fingerprints.json"


def _feed(h, name, value):
    """Hash ``value`` (arrays, numbers, dicts and lists of them) under ``name``."""
    if isinstance(value, dict):
        for key in sorted(value, key=str):
            _feed(h, f"{name}.{key}", value[key])
        return
    if isinstance(value, (list, tuple)) and value and not isinstance(value[0], (str, bytes)):
        try:
            value = np.asarray(value)
        except ValueError:
            for i, v in enumerate(value):
                _feed(h, f"{name}[{i}]", v)
            return
    if isinstance(value, (bool, int, float, np.generic, np.ndarray)):
        a = np.ascontiguousarray(np.asarray(value))
        if a.dtype == object:
            return
        h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.tobytes())


# Measured, not computed: wall times differ from run to run. A map's
# ``log_scale`` is a drawing hint copied from its indicator's declaration,
# not a number the run computed.
_SKIP = {"provenance", "accuracy", "wall_times", "log_scale"}


def fingerprint(result):
    """SHA-256 (hex, 16 characters) of every number a result holds."""
    h = hashlib.sha256()
    if dataclasses.is_dataclass(result):
        for f in dataclasses.fields(result):
            if f.name not in _SKIP:
                _feed(h, f.name, getattr(result, f.name))
        prov = getattr(result, "provenance", None)
        if prov is not None:
            # The step the run took (chosen by a pilot when not given). Not
            # the evaluation counts: the first kick of every compiled call
            # evaluates its forces afresh, so they depend on the chunking,
            # which follows wall time.
            _feed(h, "tau", prov.tau)
    else:
        _feed(h, "value", result)
    return h.hexdigest()[:16]


# -- the cases --------------------------------------------------------------------------

def cases():
    """(label, thunk) pairs; each thunk runs one short computation."""
    import sympy as sp

    import varint
    from varint.models import (DDNLS, FPUT, CoupledStandardMaps, DisorderedKG, FPUBeta,
                               StandardMap, from_map, from_potential)
    from varint.schemes import ProcessedScheme, registered

    out = []
    add = out.append
    hh, r1 = varint.paper_orbit("R1")
    _, c1 = varint.paper_orbit("C1")
    three, r2 = varint.paper_orbit("R2")
    fpu, r3 = varint.paper_orbit("R3")
    big = FPUBeta(20, 1.0)               # beyond the generated steppers: the generic one
    xb = np.zeros(40)
    xb[:20] = 0.1 * np.sin(np.arange(1, 21))
    xb[20:] = 0.05 * np.cos(np.arange(1, 21))

    # TM: every two-part scheme (and processed scheme) on the generated
    # stepper (HH, 3-dof) and the generic one (FPU-beta n = 20), the
    # spectrum (QR) and GALI (normalise).
    processed = {s.name.upper() for s in registered() if isinstance(s, ProcessedScheme)}
    for name in (s.name.upper() for s in registered()
                 if s.name.upper() in processed or s in registered(2)):
        add((f"tm/{name}/HH/lyapunov", lambda s=name: varint.lyapunov_spectrum(
            hh, c1, 50.0, tau=0.05, scheme=s)))
        add((f"tm/{name}/ThreeDof/gali", lambda s=name: varint.gali(
            three, r2, 30.0, tau=0.05, k=(2, 3), scheme=s)))
        if name not in processed:   # a lattice's part stepper applies no processor
            add((f"tm/{name}/FPU20/lyapunov2", lambda s=name: varint.lyapunov_spectrum(
                big, xb, 20.0, tau=0.05, n_exponents=2, scheme=s)))
        add((f"tm/{name}/HH/integrate", lambda s=name: varint.integrate(
            hh, r1, 20.0, tau=0.05, scheme=s, t_out=5,
            deviations=np.eye(4)[:, :2])))
    # Every indicator on the generated stepper and on the generic one.
    for ind in ("gali", "sali", "local_exponents", "lyapunov", "megno", "fli", "ofli"):
        opts = {"window": 10.0} if ind == "local_exponents" else {}
        add((f"tm/SBAB2C/HH/ind/{ind}", lambda i=ind, o=opts: varint.run(
            hh, c1, i, 40.0, tau=0.05, **o)))
        # A lattice's own default is ABA864 on its part stepper: SBAB2C named.
        add((f"tm/SBAB2C/FPU20/ind/{ind}", lambda i=ind, o=opts: varint.run(
            big, xb, i, 10.0, tau=0.05, scheme="SBAB2C", **o)))
    add(("tm/SBAB2C/R3/lyapunov", lambda: varint.lyapunov_spectrum(fpu, r3, 30.0, tau=0.05,
                                                                  scheme="SBAB2C")))
    # Batches, serial and parallel (lanes), with every accumulator.
    X = np.array([r1, c1, 0.99 * c1])
    for ind in ("sali", "megno", "fli", "lyapunov", "gali"):
        for parallel in (False, True):
            add((f"tm/SRKN14A/HH/batch/{ind}/parallel={parallel}",
                 lambda i=ind, p=parallel: varint.run(hh, X, i, 40.0, tau=0.1,
                                                       scheme="SRKN14a", parallel=p)))
    # The automatic step (pilot) and sparse renormalisation.
    add(("tm/auto/HH/lyapunov", lambda: varint.lyapunov_spectrum(hh, c1, 200.0)))
    add(("tm/auto/HH/megno", lambda: varint.megno(hh, r1, 200.0)))
    add(("tm/every/HH/lyapunov", lambda: varint.lyapunov_spectrum(
        hh, c1, 100.0, tau=0.05, renormalize_every=4)))
    # from_potential and a time-dependent potential (extended phase space).
    x, y, q, t = sp.symbols("x y q t")
    quartic = from_potential((x**2 + y**2) / 2 + x**2 * y - y**3 / 3
                             + sp.Rational(1, 10) * x**4, [x, y],
                             inverse_mass=[1, sp.sqrt(2)], name="quartic HH")
    forced = from_potential(-sp.cos(q) * (1 + sp.Rational(1, 5) * sp.cos(sp.Rational(3, 2) * t)),
                            [q], time=t)
    for s in ("SBAB2C", "ABA864", "SABA2C"):
        add((f"tm/{s}/quartic/lyapunov", lambda s=s: varint.lyapunov_spectrum(
            quartic, [0.0, 0.1, 0.3, 0.2], 50.0, tau=0.05, scheme=s)))
        add((f"tm/{s}/forced/lyapunov", lambda s=s: varint.lyapunov_spectrum(
            forced, [0.0, 2.0], 50.0, tau=0.05, scheme=s)))
    add(("tm/SBAB2C/forced/megno", lambda: varint.megno(forced, [0.0, 2.0], 50.0, tau=0.05)))
    # Lattices: every k-part scheme, the part stepper and the small chains'
    # generated two-part path.
    kg = DisorderedKG(32, W=4.0, seed=1)
    kg_small = DisorderedKG(8, W=4.0, seed=2)
    fput = FPUT(32, alpha=0.25, beta=1.0)
    dd = DDNLS(32, W=4.0, beta=1.0, seed=1)
    dd2 = DDNLS((6, 6), W=4.0, beta=1.0, seed=1)
    kg2 = DisorderedKG((6, 6), W=4.0, seed=1)
    for name, model, x0 in (("KG32", kg, kg.initial_block(4, 0.4)),
                            ("KG8", kg_small, kg_small.initial_block(2, 0.4)),
                            ("FPUT32", fput, fput.initial_block(4, 0.4)),
                            ("KG6x6", kg2, kg2.initial_block(2, 0.4))):
        for s in ("ABA864", "SBAB2C", "SRKN14A", "ABC2"):
            if s == "ABC2":
                continue
            add((f"tm/{s}/{name}/dvd", lambda m=model, x=x0, s=s: varint.run(
                m, x, "dvd", 5.0, 0.1, scheme=s)))
        add((f"tm/ABA864/{name}/lyapunov2", lambda m=model, x=x0: varint.run(
            m, x, "lyapunov", 5.0, 0.1, scheme="ABA864", n_exponents=2)))
        add((f"tm/ABA864/{name}/megno", lambda m=model, x=x0: varint.run(
            m, x, "megno", 5.0, 0.1, scheme="ABA864")))
    # The lattices' defaults: their own scheme (the part stepper; the
    # generated one for KG8), at a given and at the pilot's step.
    for name, model, x0 in (("KG32", kg, kg.initial_block(4, 0.4)),
                            ("KG8", kg_small, kg_small.initial_block(2, 0.4)),
                            ("FPUT32", fput, fput.initial_block(4, 0.4)),
                            ("DDNLS32", dd, dd.initial_block(4, 1.0))):
        add((f"tm/default/{name}/dvd", lambda m=model, x=x0: varint.run(m, x, "dvd", 5.0, 0.1)))
        add((f"tm/auto/{name}/dvd", lambda m=model, x=x0: varint.run(m, x, "dvd", 5.0)))
    for name, model, x0 in (("DDNLS32", dd, dd.initial_block(4, 1.0)),
                            ("DDNLS6x6", dd2, dd2.initial_block(2, 1.0))):
        for s in (s.name.upper() for s in registered(3)):
            add((f"tm/{s}/{name}/spreading", lambda m=model, x=x0, s=s: varint.run(
                m, x, "dvd", 3.0, 0.1, scheme=s)))
        add((f"tm/ABA864/{name}/two-part", lambda m=model, x=x0: varint.run(
            m, x, "dvd", 3.0, 0.1, scheme="ABA864")))
    # Maps.
    sm = StandardMap(1.2)
    cm = CoupledStandardMaps(1.5, 1.5, 0.1)
    xs, ps = sp.symbols("x p")
    p1 = ps + 1.2 * sp.sin(xs)
    mine = from_map([xs + p1, p1], [xs, ps], periods={xs: 2 * sp.pi})
    for name, model, x0 in (("standard", sm, [1.0, 0.5]),
                            ("coupled", cm, [0.55, 0.1, 0.005, 0.015]),
                            ("from_map", mine, [1.0, 0.5])):
        for ind in ("lyapunov", "gali", "sali", "megno", "fli"):
            add((f"map/{name}/{ind}", lambda m=model, x=x0, i=ind: varint.run(m, x, i, 300)))
        add((f"two-particle/{name}/x1", lambda m=model, x=x0: varint.run(
            m, x, "x1", 300, method="two-particle")))
    # The other methods.
    for method, opts in (("tdhcc", {}), ("tdhes", {}), ("tdheps", {}),
                         ("tdhcc", {"scheme": "ABA864"}), ("tdhes", {"eigensolver": "analytic"}),
                         ("tdheps", {"tangent_scheme": "SBAB1"}),
                         ("two-particle", {}), ("two-particle", {"d_max": 1e-6}),
                         ("taylor", {}), ("cvode", {}), ("dop853", {})):
        label = method + "".join(f"/{k}={v}" for k, v in opts.items())
        add((f"{label}/HH/lyapunov", lambda m=method, o=opts: varint.lyapunov_spectrum(
            hh, c1, 20.0, tau=0.05, method=m, **o)))
        add((f"{label}/HH/megno", lambda m=method, o=opts: varint.megno(
            hh, r1, 20.0, tau=0.05, method=m, **o)))
    for method in ("tdhcc", "two-particle", "dop853", "cvode", "taylor"):
        add((f"{method}/forced/lyapunov", lambda m=method: varint.lyapunov_spectrum(
            forced, [0.0, 2.0], 10.0, tau=0.05, method=m)))
        add((f"{method}/FPU20/lyapunov2", lambda m=method: varint.lyapunov_spectrum(
            big, xb, 5.0, tau=0.05, method=m, n_exponents=2)))
    add(("two-particle/KG32/x1", lambda: varint.run(kg, kg.initial_block(4, 0.4), "x1", 3.0,
                                                    0.1, method="two-particle")))
    # Workflows: chaos maps (defaults and given τ), an ensemble, sections.
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.4, 0.6, 7), np.linspace(-0.4, 0.4, 7))
    for ind in ("sali", "megno", "fli", "x1"):
        add((f"chaos_map/HH/{ind}/defaults", lambda i=ind: varint.chaos_map(
            hh, grid, i, t_end=200.0, progress=False)))
        add((f"chaos_map/HH/{ind}/tau", lambda i=ind: varint.chaos_map(
            hh, grid, i, t_end=200.0, tau=0.05, chunk_size=8, progress=False)))
    sgrid = varint.phase_grid(sm, np.linspace(0, 6, 8), np.linspace(-3, 3, 8))
    add(("chaos_map/standard/sali", lambda: varint.chaos_map(sm, sgrid, "sali", t_end=500,
                                                       progress=False)))
    add(("ensemble/KG/dvd", lambda: varint.ensemble(
        DisorderedKG, range(1, 4), lambda m, s: m.initial_block(4, 0.4), "dvd", 3.0, 0.1,
        params={"shape": 16, "W": 4.0}, scheme="ABA864", progress=False)))
    add(("section/HH", lambda: varint.surface_of_section(hh, c1, 200.0)))
    add(("section/HH/batch", lambda: varint.surface_of_section(hh, X, 100.0, tau=0.02,
                                                               scheme="SBAB2C")))
    labels = [label for label, _ in out]
    assert len(set(labels)) == len(labels), "fingerprint labels must be unique"
    return out


def compute(only=None):
    """{label: fingerprint} of every case (``only``: label prefixes)."""
    import warnings

    out, took = {}, {}
    for label, thunk in cases():
        if only and not any(label.startswith(p) for p in only):
            continue
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                value = fingerprint(thunk())
            except Exception as exc:    # a case that fails is a fingerprint too
                value = f"error: {type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
        out[label] = value
        took[label] = time.perf_counter() - start
        print(f"{label:60s} {value}  ({took[label]:.2f} s)", flush=True)
    return out


def machine():
    """What the bits depend on besides varint's code."""
    from varint.results import package_versions

    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        cpu = platform.processor()
    # The model name alone does not tell the bits: "AMD EPYC" is a Zen 3
    # without AVX-512 as well as a Zen 4 with it, and numba compiles for the
    # CPU it runs on (LLVM's name of it), NumPy dispatches its loops by the
    # features it finds (its power is SVML's under AVX-512).
    import llvmlite.binding as llvm
    from numba.core import config

    return {"cpu": cpu, "llvm_cpu": config.CPU_NAME or llvm.get_host_cpu_name(),
            "avx512f": bool(_numpy_cpu().get("AVX512F")), "machine": platform.machine(),
            "versions": package_versions()}


def _numpy_cpu():
    """NumPy's view of the CPU's features (its SIMD dispatch)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:
        return {}
    return __cpu_features__


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="store the fingerprints")
    mode.add_argument("--check", action="store_true", help="compare with the stored ones")
    parser.add_argument("--only", nargs="*", default=None, help="label prefixes to run")
    parser.add_argument("--store", type=Path, default=STORE)
    parser.add_argument("--tiny-chunks", action="store_true",
                        help="advance runs in chunks of a step or two (chunking must not "
                             "change a bit)")
    args = parser.parse_args(argv)
    if args.tiny_chunks:
        from varint import driver

        # Chunks are paced by wall time; make every chunk as short as it can be.
        driver.CHUNK_SECONDS, driver._QUICK_CHUNK = 1e-9, 0.0
    now = compute(args.only)
    if args.write:
        old = json.loads(args.store.read_text())["cases"] if args.store.exists() and args.only \
            else {}
        old.update(now)
        args.store.write_text(json.dumps({"machine": machine(), "cases": old}, indent=1,
                                         sort_keys=True) + "\n")
        print(f"{len(now)} fingerprints written to {args.store}")
        return 0
    stored = json.loads(args.store.read_text())
    if stored["machine"] != machine():
        print(f"note: stored on {stored['machine']}, checking on {machine()}: bits may differ "
              "for reasons other than the code")
    changed = [k for k in now if stored["cases"].get(k) != now[k]]
    missing = [k for k in stored["cases"] if k not in now
               and (not args.only or any(k.startswith(p) for p in args.only))]
    for k in changed:
        print(f"CHANGED {k}: {stored['cases'].get(k)} -> {now[k]}")
    for k in missing:
        print(f"MISSING {k}")
    print(f"{len(now)} cases, {len(changed)} changed, {len(missing)} missing")
    return 1 if changed or missing else 0


if __name__ == "__main__":
    sys.exit(main())
