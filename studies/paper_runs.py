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
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import varint
from varint.checkpoint import read as read_checkpoint
from varint.state import output_steps

__all__ = ["PAPER_TAU", "PAPER_DELTA", "SEED", "Stored", "run", "run_key", "method_options",
           "METHOD_LABELS", "longest_stored", "horizon"]

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
    transformation (paper eq. A.10) for TDHes on Hénon–Heiles, and
    δ = ``delta`` (1e-5 by default) for DOP853."""
    if method == "dop853":
        return {"delta": PAPER_DELTA if delta is None else delta}
    if method == "tdhes" and orbit in ("R1", "C1", "C2"):
        return {"eigensolver": "analytic"}
    return {}


@dataclass
class Stored:
    """A stored run: the result and how long it took.

    Attributes
    ----------
    key : str
    result : LyapunovResult or GALIResult
    cpu : float
        CPU seconds (``time.process_time``); for a run resumed from a
        checkpoint, the CPU time of the last session divided by the share of
        the steps it did (``resumed`` is then True).
    wall : float
        Wall seconds of the whole run (all sessions).
    resumed : bool
    """

    key: str
    result: object
    cpu: float
    wall: float
    resumed: bool

    @property
    def t(self):
        return self.result.t


def run_key(kind, orbit, method, tau, t_end, options):
    """File name stem of a run: everything that selects it."""
    opts = "".join(f"-{k}{v:g}" if isinstance(v, float) else f"-{k}{v}"
                   for k, v in sorted(options.items()))
    return f"{kind}-{orbit}-{method}{opts}-tau{tau:g}-t{t_end:g}"


def _key_options(kind, model, method, orbit, delta, orders):
    options = method_options(method, orbit, delta)
    if kind == "gali":
        orders = tuple(range(2, model.dim + 1)) if orders is None else tuple(orders)
        return options, orders, dict(options, k="_".join(map(str, orders)))
    return options, orders, options


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
        return Stored(key, varint.load_result(path), meta["cpu"], meta["wall"], meta["resumed"])

    (store / "checkpoints").mkdir(parents=True, exist_ok=True)
    checkpoint = store / "checkpoints" / f"{key}.ckpt"
    if fresh and checkpoint.exists():
        checkpoint.unlink()
    t_out = output_steps(t_end, tau, per_decade=PER_DECADE) * tau
    # Where a checkpoint resumes the run: the CPU time of earlier sessions is
    # not recorded, so this session's is scaled by the share of the steps it
    # did.
    start = read_checkpoint(checkpoint).state.step if checkpoint.exists() else 0
    # Compile the kernels first, so the CPU time is that of the integration.
    _call(kind, model, x0, 20 * tau, tau, method, orders, None, False, None, options)
    c0, w0 = time.process_time(), time.perf_counter()
    result = _call(kind, model, x0, t_end, tau, method, orders, t_out, progress, checkpoint,
                   options)
    cpu, wall_session = time.process_time() - c0, time.perf_counter() - w0
    if result.interrupted:
        raise KeyboardInterrupt(f"run {key} interrupted at t = {result.t[-1]:g}; its "
                                f"checkpoint {checkpoint} resumes it when the study is "
                                "started again")
    wall = float(result.provenance.wall_time)
    resumed = start > 0
    if resumed:
        total = result.provenance.counts["steps"]
        cpu *= total / (total - start)
    result.save(path)
    meta_path.write_text(json.dumps({"kind": kind, "orbit": orbit, "method": method,
                                     "options": options, "tau": tau, "t_end": t_end,
                                     "cpu": cpu, "wall": wall, "wall_session": wall_session,
                                     "resumed": resumed}, indent=1))
    checkpoint.unlink(missing_ok=True)
    return Stored(key, result, cpu, wall, resumed)
