"""Shared plumbing of the studies: where results go, how claims are
recorded for REPORT.md, and the ``--quick``/full command line.

Every study is a script ``studies/<name>.py`` with ``main(argv)`` returning a
dict of its results. Full runs write into ``studies/results/`` (committed);
``--quick`` runs write into ``--out`` (default ``studies/results/quick/``,
not committed) and are what the test suite runs.

A *claim* is one line of the paper's (its figures and tables) or of our own
questions, with the paper's figure, ours, whether it holds, and the rules
of :mod:`studies.claims` that decided it. Each study saves its claims as
``<name>.claims.json``; ``studies/report.py`` assembles them into
``REPORT.md``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"


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


def save_json(out, name, data):
    """Write ``data`` as ``out/name.json`` (atomically) and return the path."""
    path = Path(out) / f"{name}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(_plain(data), indent=1))
    os.replace(tmp, path)
    return path


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
