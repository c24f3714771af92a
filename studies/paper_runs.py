"""The paper's runs, computed once and stored: what Table I and Figs. 2–11
share.

Table I and Figs. 2–3 read the same twelve R1 runs, and a full run of the
studies takes hours, so every run is stored under ``<out>/runs/`` as the
result file (``.npz``, :meth:`varint.results.LyapunovResult.save`) and a
JSON sidecar with its CPU time. Asking again for a stored run loads it;
``fresh=True`` recomputes it. While it runs, a run writes a checkpoint to
``<out>/runs/checkpoints/`` every minute, so an interrupted study (Ctrl-C,
a killed job) resumes where it stopped when started again; the checkpoint
is deleted once the result is stored.

Every run starts from the same seeded random deviation vectors (seed 0),
as the paper compares methods on the same orbit, and records outputs at
log-spaced times, 20 per decade (the paper's plots are log-log).

CPU time is ``time.process_time()`` of the run, after a short warm-up run
that compiles the method's kernels (so it is not counted). The machine is
shared, so compare CPU times as ratios between rows of one study run; the
wall time is kept beside it.

A run that stops and resumes is timed over all its sessions by varint
itself: each checkpoint carries the CPU time spent so far, measured in
every session (``provenance.cpu_time``, :mod:`varint.checkpoint`), and the
sidecar stores that (``cpu_basis`` "measured"). Only sidecars written
before varint measured it — runs resumed from a checkpoint whose earlier
sessions were not timed — have their CPU extrapolated from the last
session, and their ``cpu_basis`` says so and by what share. The sidecar
also names the code that ran and the machine (:mod:`varint.identity`).

Run one stored run from the command line (resumable: run it again after
an interruption)::

    python -m studies.paper_runs lyapunov C1 dop853 --tau 0.05 --t-end 1e8
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import varint  # noqa: E402
from varint import identity  # noqa: E402
from varint.checkpoint import read as read_checkpoint  # noqa: E402
from varint.state import output_steps  # noqa: E402

__all__ = ["PAPER_TAU", "PAPER_DELTA", "SEED", "Stored", "run", "run_key", "stored_key",
           "method_options",
           "METHOD_LABELS", "longest_stored", "horizon", "cpu_basis"]

#: The paper's renormalisation interval τ and DOP853 threshold δ (Sect. VI).
PAPER_TAU = 0.05
PAPER_DELTA = 1e-5
#: Seed of the initial deviation vectors of every run.
SEED = 0
#: Output times per decade.
PER_DECADE = 20

#: How the paper names the methods.
METHOD_LABELS = {"dop853": "DOP853", "tdhcc": "TDHcc", "tdhes": "TDHes", "tdheps": "TDHeps",
                 "tm": "TM"}


def method_options(method, orbit, delta=None):
    """The paper's settings of ``method`` on ``orbit``: SBAB2C for the
    symplectic methods (the default of varint's), the closed-form
    transformation (paper eq. A.10) for TDHes on Hénon–Heiles, δ = ``delta``
    (1e-5 by default) for DOP853, and for TM the vectors renormalised every
    τ as in the paper (``renormalize_every=1``; varint's default
    renormalises adaptively, which gives the same exponents to round-off at
    a fraction of the cost, but Table I compares methods that all
    renormalise every τ)."""
    if method == "dop853":
        return {"delta": PAPER_DELTA if delta is None else delta}
    if method == "tdhes" and orbit in ("R1", "C1", "C2"):
        return {"eigensolver": "analytic"}
    if method == "tm":
        return {"renormalize_every": 1}
    return {}


#: Options every stored run's key leaves out: they are the paper's and were
#: varint's only behaviour when the first runs were stored (TM renormalised
#: every τ before ``renormalize_every`` existed).
_IMPLIED = ("renormalize_every",)


@dataclass
class Stored:
    """A stored run: the result and how long it took.

    Attributes
    ----------
    key : str
    result : LyapunovResult or GALIResult
    cpu : float
        CPU seconds (``time.process_time``) over all sessions
        (``provenance.cpu_time`` of the result).
    wall : float
        Wall seconds of the whole run (all sessions).
    resumed : bool
        Whether the run took more than one session.
    cpu_basis : str
        "measured", or how ``cpu`` was extrapolated (a run resumed from a
        checkpoint whose earlier sessions were not timed: the last
        session's CPU divided by
        the share of the steps it did).
    meta : dict
        The whole sidecar (code, machine, this session's CPU and wall).
    """

    key: str
    result: object
    cpu: float
    wall: float
    resumed: bool
    cpu_basis: str = "measured"
    meta: dict = field(default_factory=dict)

    @property
    def t(self):
        return self.result.t


def run_key(kind, orbit, method, tau, t_end, options):
    """File name stem of a run: everything that selects it."""
    opts = "".join(f"-{k}{v:g}" if isinstance(v, float) else f"-{k}{v}"
                   for k, v in sorted(options.items()))
    return f"{kind}-{orbit}-{method}{opts}-tau{tau:g}-t{t_end:g}"


def stored_key(kind, orbit, method, tau, t_end, delta=None, orders=None):
    """The file name stem under which :func:`run` stores this run."""
    model, _ = varint.paper_orbit(orbit)
    _, _, key_options = _key_options(kind, model, method, orbit, delta, orders)
    return run_key(kind, orbit, method, tau, t_end, key_options)


def _key_options(kind, model, method, orbit, delta, orders):
    options = method_options(method, orbit, delta)
    key = {k: v for k, v in options.items() if k not in _IMPLIED}
    if kind == "gali":
        orders = tuple(range(2, model.dim + 1)) if orders is None else tuple(orders)
        return options, orders, dict(key, k="_".join(map(str, orders)))
    return options, orders, key


def longest_stored(out, kind, orbit, method, tau, *, orders=None, delta=None):
    """The horizon of the longest stored run of this kind, orbit, method, τ
    (and orders, δ), or None: a study asks for its default horizon or the
    longest run already stored, whichever is longer, so that a longer run
    (e.g. a DOP853 run of C2 to the paper's 1e8) replaces the shorter one in
    every claim without a change of code."""
    model, _ = varint.paper_orbit(orbit)
    _, _, key_options = _key_options(kind, model, method, orbit, delta, orders)
    stem = run_key(kind, orbit, method, tau, 1.0, key_options).rsplit("-t", 1)[0]
    ends = [float(p.stem.rsplit("-t", 1)[1]) for p in (Path(out) / "runs").glob(f"{stem}-t*.npz")
            if (p.with_suffix(".json")).exists()]
    return max(ends, default=None)


def horizon(out, kind, orbit, method, tau, default, *, requested=None, orders=None,
            delta=None):
    """The horizon a study uses for a run: the longest of its ``default``,
    a ``requested`` one (computed if not stored) and the longest stored run
    (:func:`longest_stored`)."""
    stored = longest_stored(out, kind, orbit, method, tau, orders=orders, delta=delta)
    return max(default, requested or 0.0, stored or 0.0)


def _call(kind, model, x0, t_end, tau, method, orders, t_out, progress, checkpoint, options):
    common = dict(tau=tau, method=method, seed=SEED, t_out=t_out, progress=progress,
                  checkpoint=checkpoint, **options)
    if kind == "lyapunov":
        return varint.lyapunov_spectrum(model, x0, t_end, **common)
    return varint.gali(model, x0, t_end, k=orders, **common)


def run(out, kind, orbit, method, tau, t_end, *, orders=None, delta=None, fresh=False,
        progress=None):
    """The run ``kind`` of ``orbit`` by ``method`` to ``t_end``, stored in
    ``out/runs`` (computed, resumed from a checkpoint, or loaded).

    Parameters
    ----------
    out : path
        The study's results directory.
    kind : {"lyapunov", "gali"}
        The full Lyapunov spectrum (QR every τ) or GALIs (normalisation
        every τ).
    orbit : {"R1", "C1", "C2", "R2", "R3"}
    method : str
        "tm", "tdhcc", "tdhes", "tdheps" or "dop853", with the paper's
        settings (:func:`method_options`).
    tau, t_end : float
    orders : sequence of int, optional
        GALI orders (2..2N by default).
    delta : float, optional
        DOP853 threshold (1e-5 by default).
    fresh : bool
        Recompute even if stored.
    progress : bool, optional
        Progress bar (by default when stderr is a terminal).

    Returns
    -------
    Stored
    """
    if kind not in ("lyapunov", "gali"):
        raise ValueError(f"kind must be 'lyapunov' or 'gali', got {kind!r}")
    model, x0 = varint.paper_orbit(orbit)
    options, orders, key_options = _key_options(kind, model, method, orbit, delta, orders)
    key = run_key(kind, orbit, method, tau, t_end, key_options)
    store = Path(out) / "runs"
    path, meta_path = store / f"{key}.npz", store / f"{key}.json"
    if not fresh and path.exists() and meta_path.exists():
        meta = json.loads(meta_path.read_text())
        return Stored(key, varint.load_result(path), meta["cpu"], meta["wall"], meta["resumed"],
                      cpu_basis(meta), meta)

    (store / "checkpoints").mkdir(parents=True, exist_ok=True)
    checkpoint = store / "checkpoints" / f"{key}.ckpt"
    if fresh:
        checkpoint.unlink(missing_ok=True)
    t_out = output_steps(t_end, tau, per_decade=PER_DECADE) * tau
    start = read_checkpoint(checkpoint).state.step if checkpoint.exists() else 0
    code, machine = identity.code_identity(), identity.machine()
    # Compile the kernels first, so the CPU time is that of the integration.
    _call(kind, model, x0, 20 * tau, tau, method, orders, None, False, None, options)
    c0, w0 = time.process_time(), time.perf_counter()
    result = _call(kind, model, x0, t_end, tau, method, orders, t_out, progress, checkpoint,
                   options)
    session, wall_session = time.process_time() - c0, time.perf_counter() - w0
    if result.interrupted:
        raise KeyboardInterrupt(f"run {key} interrupted at t = {result.t[-1]:g}; its "
                                f"checkpoint {checkpoint} resumes it when the study is "
                                "started again")
    wall = float(result.provenance.wall_time)
    cpu = result.provenance.cpu_time
    if cpu is None:
        # Resumed from a checkpoint whose earlier sessions were not timed:
        # this session's CPU is scaled by its share of the steps.
        total = result.provenance.counts["steps"]
        share = (total - start) / total
        cpu, basis = session / share, (f"extrapolated: the last session's CPU over the "
                                       f"{share:.0%} of the steps it did")
    else:
        cpu, basis = float(cpu), "measured"
    result.save(path)
    meta = {"kind": kind, "orbit": orbit, "method": method, "options": options, "tau": tau,
            "t_end": t_end, "cpu": cpu, "cpu_basis": basis, "cpu_session": session,
            "wall": wall, "wall_session": wall_session, "resumed": bool(start),
            "code": code, "machine": machine}
    meta_path.write_text(json.dumps(meta, indent=1))
    checkpoint.unlink(missing_ok=True)
    return Stored(key, result, cpu, wall, bool(start), basis, meta)


def cpu_basis(meta):
    """How a stored run's CPU time was obtained: its sidecar's
    ``cpu_basis``, or for a sidecar written before it was recorded,
    "extrapolated" when the run was resumed (its CPU was then scaled from
    the last session) and "measured" otherwise."""
    if "cpu_basis" in meta:
        return meta["cpu_basis"]
    return "extrapolated: the last session's CPU over its share of the steps" \
        if meta["resumed"] else "measured"


def main(argv=None):
    """Compute (or resume, or load) one stored run; print its CPU time."""
    parser = argparse.ArgumentParser(description="One of the paper's stored runs.")
    parser.add_argument("kind", choices=("lyapunov", "gali"))
    parser.add_argument("orbit", choices=("R1", "C1", "C2", "R2", "R3"))
    parser.add_argument("method", choices=tuple(METHOD_LABELS))
    parser.add_argument("--tau", type=float, default=PAPER_TAU)
    parser.add_argument("--t-end", type=float, required=True)
    parser.add_argument("--delta", type=float, default=None)
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    parser.add_argument("--fresh", action="store_true")
    args = parser.parse_args(argv)
    s = run(args.out, args.kind, args.orbit, args.method, args.tau, args.t_end,
            delta=args.delta, fresh=args.fresh)
    print(f"{s.key}: t = {s.t[-1]:g}, CPU {s.cpu:.1f} s ({s.cpu_basis}), wall {s.wall:.1f} s")
    return s


if __name__ == "__main__":
    main()
