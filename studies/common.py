"""Shared plumbing of the studies: where results go, how claims are
recorded for REPORT.md, and the ``--quick``/full command line.

Every study is a script ``studies/<name>.py`` with ``main(argv)`` returning a
dict of its results. Full runs write into ``studies/results/`` (committed);
``--quick`` runs write into ``--out`` (default ``studies/results/quick/``,
not committed) and are what the test suite runs.

Every JSON output (:func:`save_json`) carries ``_provenance``: the code
that ran (:func:`varint.identity.code_identity`: the digest of varint's
sources and the git commit), the machine with its load when the study
started and when the file was written, the command, and how its times were
obtained (measured, or derived and how). Timings go through
:func:`interleaved`: contenders taken in turn, the minimum of repeats.

A *claim* is one line of the paper's (its figures and tables) or of our own
questions, with the paper's figure, ours, whether it holds, and the rules
of :mod:`studies.claims` that decided it. Each study saves its claims as
``<name>.claims.json``; ``studies/report.py`` assembles them into
``REPORT.md``.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import hashlib
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from varint import identity

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
#: The machine when the study started (its load, above all) and the code
#: that runs: this module is imported by every study before it does any
#: work (the code identity is not worked out at the end, when the sources
#: on disk may have changed).
STARTED = identity.machine()


def _studies_digest():
    # A study's output depends on the studies' code too.
    h = hashlib.sha256()
    for path in sorted(HERE.glob("*.py")):
        h.update(path.name.encode() + path.read_bytes())
    return h.hexdigest()


CODE = {**identity.code_identity(), "studies": _studies_digest()}
#: What ``_provenance.times`` says when a study does not say otherwise.
MEASURED = "measured: wall or CPU time of the runs themselves (see the study's docstring)"
#: A contender whose call takes less than this many seconds is called again
#: within its turn (:func:`interleaved`).
SHORT = 0.02


def parse_args(description, argv=None, extra=None):
    """The common command line: ``--quick`` and ``--out``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true",
                        help="short horizons (seconds to a minute), as run by the tests")
    parser.add_argument("--out", type=Path, default=None,
                        help="results directory (default studies/results[/quick])")
    if extra:
        extra(parser)
    args = parser.parse_args(argv)
    if args.out is None:
        args.out = RESULTS / "quick" if args.quick else RESULTS
    args.out.mkdir(parents=True, exist_ok=True)
    return args


def _plain(obj):
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return str(obj)
    return obj


def provenance(times=MEASURED):
    """What produced a study's output: ``code`` (varint's source digest, the
    git commit, and ``studies``: the digest of the studies' own ``.py``
    files), ``machine`` (CPU model, cores, load when the study started),
    ``load_end`` (the load now), ``command``, ``created`` and ``times`` (how
    the times in it were obtained: "measured…", or what was derived and how;
    a dict when fields differ)."""
    return {"code": dict(CODE), "machine": dict(STARTED),
            "load_end": identity.machine()["load"],
            "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
            "created": datetime.datetime.now(datetime.timezone.utc).isoformat(
                timespec="seconds"),
            "times": times}


def save_json(out, name, data, times=MEASURED, judged_again=False):
    """Write ``data`` as ``out/name.json`` (atomically) and return the path.

    A dict gets the key ``_provenance`` (:func:`provenance`, with ``times``);
    a list (a claims file) is written as it is: the study's own JSON
    beside it carries the provenance. With ``judged_again``, ``data`` keeps
    the ``_provenance`` of the run that measured it, and records this
    process's under ``judged_again`` (claims re-judged from stored
    measurements)."""
    path = Path(out) / f"{name}.json"
    if isinstance(data, dict) and judged_again and "_provenance" in data:
        data = {**data, "_provenance": {**data["_provenance"],
                                        "judged_again": provenance("no time measured")}}
    elif isinstance(data, dict):
        data = {**data, "_provenance": provenance(times)}
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(_plain(data), indent=1))
    os.replace(tmp, path)
    return path


def interleaved(tasks, repeats, self_timed=(), clock=time.perf_counter, turns=None):
    """Each callable of ``tasks`` (label -> callable) run ``repeats`` times
    in turn (a, b, c, a, b, c, …, so that the load of the shared machine
    falls on every contender alike); returns (label -> best seconds per
    call, label -> last output). Within a turn a task is called until
    :data:`SHORT` seconds have passed (at least once) and its time is the
    mean per call, as ``timeit`` does: a call of a millisecond made right
    after another contender's runs mostly on the caches that one left. The
    callables named in ``self_timed`` return (seconds, output) measured by
    themselves (a C loop's own clock, a loop that leaves out a
    compilation); they are called once per turn. ``clock`` is wall time by
    default; ``time.process_time`` (this process's CPU time) keeps the
    time other jobs of a loaded machine take from a single-threaded
    contender out of its figure. A dict ``turns`` receives every turn's
    seconds per call (label -> list), from which :func:`ratio_spread`
    gives the spread of a ratio over the repeats."""
    best, out = dict.fromkeys(tasks, math.inf), {}
    for _ in range(repeats):
        for label, task in tasks.items():
            calls, t0 = 0, clock()
            while True:
                out[label] = task()
                calls += 1
                elapsed = clock() - t0
                if label in self_timed or elapsed >= SHORT:
                    break
            seconds = elapsed / calls
            if label in self_timed:
                seconds, out[label] = out[label]
            best[label] = min(best[label], seconds)
            if turns is not None:
                turns.setdefault(label, []).append(seconds)
    return best, out


def ratio_spread(turns, a, b):
    """The ratio of contender ``b``'s time to ``a``'s in each turn of
    :func:`interleaved` (how many times faster ``a`` is): (smallest,
    largest) over the turns, or None without per-turn times."""
    if not turns or a not in turns or b not in turns:
        return None
    ratios = [tb / ta for ta, tb in zip(turns[a], turns[b], strict=True)]
    return min(ratios), max(ratios)


def save_csv(out, name, rows, columns):
    """Write a list of dicts as ``out/name.csv`` with the given columns."""
    path = Path(out) / f"{name}.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for row in rows:
            w.writerow([_fmt(row.get(c)) for c in columns])
    return path


def _fmt(v):
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.6g}"
    return v


class Claims:
    """Collects claims of one study and saves them for REPORT.md.

    Parameters
    ----------
    study : str
        Name of the claims file, ``<study>.claims.json``.
    out : path
    source : {"paper", "own"}, optional
        Whose claims they are by default: the paper's (its text, tables and
        figures) or varint's own checks; without it, the report decides by
        the study (``report.PAPER``).
    """

    def __init__(self, study, out, source=None):
        self.study, self.out, self.source, self.items = study, Path(out), source, []

    def add(self, claim, paper, ours, holds, figure=None, note="", rules=(), source=None,
            checked_to=None, horizon=None):
        """Record one claim.

        Parameters
        ----------
        claim : str
            What is asserted (in the paper's words where it states it).
        paper, ours : str
            The paper's figure and ours, as text with numbers.
        holds : bool or None
            None when there is nothing to compare (a measurement only, or a
            horizon too short to tell).
        figure : str, optional
            File name of the figure that shows it.
        note : str
            Why it differs, or context. A claim that differs without a
            note is recorded with the note "unexplained".
        rules : sequence of studies.claims.Judgement
            The rules applied, with their windows and tolerances.
        source : {"paper", "own"}, optional
            Overrides the study's default.
        checked_to, horizon : float, optional
            The time up to which our runs checked the claim, and the
            paper's horizon for it; a verdict reached before the paper's
            horizon is marked as checked only that far.
        """
        if holds is False and not note:
            note = "unexplained"
        # A verdict that sits on its threshold says so, with its margin.
        edges = [j.margin() for j in rules if j.margin()]
        if edges:
            note = "; ".join([note, *edges] if note else edges)
        item = {"claim": claim, "paper": paper, "ours": ours,
                "holds": None if holds is None else bool(holds), "figure": figure,
                "note": note, "rules": [j.record() for j in rules]}
        if source or self.source:
            item["source"] = source or self.source
        if checked_to is not None and horizon is not None:
            item["checked_to"], item["horizon"] = float(checked_to), float(horizon)
        self.items.append(item)
        return holds

    def save(self):
        return save_json(self.out, f"{self.study}.claims", self.items)


class Stopwatch:
    """``with Stopwatch() as sw: ...; sw.seconds``."""

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.t0
        return False


def figure(out, name):
    """A new matplotlib figure file path and (fig, plt), Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return Path(out) / f"{name}.png", plt
