"""REPORT.md: the paper's numbers and ours side by side, assembled from the
studies' result files.

Reads, from the results directory, ``table1.csv`` (Table I, row by row),
every ``*.claims.json`` (one line per claim: the paper's number, ours,
holds / differs, the rules that decided it, with the figure shown beside
its claims) and the stored runs of :mod:`paper_runs` (their CPU times),
and writes ``REPORT.md`` there. The paper's claims and varint's own checks
are counted apart. It computes nothing: run the studies first, then this
(any time again; missing studies are listed as missing).

Usage: ``python studies/report.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import csv
import json
import re
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.claims import RULES  # noqa: E402
from studies.common import parse_args  # noqa: E402
from studies.paper_runs import PAPER_DELTA, PAPER_TAU, longest_stored  # noqa: E402

#: Sections in this order first (the paper's), then any other claims file
#: alphabetically. Name -> heading.
KNOWN = {
    "table1": "Table I — the claims of the text about it",
    "paper_fig02": "Fig. 2 — R1: finite-time Lyapunov exponents, five methods",
    "paper_fig03": "Fig. 3 — R1: step-size dependence (DOP853, TDHeps)",
    "paper_fig04": "Fig. 4 — R1: GALIs, five methods",
    "roundoff_floor": "Fig. 4's round-off floor, measured (studies/roundoff_floor.py)",
    "paper_fig05": "Fig. 5 — C1: exponents, pair sums, GALIs",
    "sections": "Figs. 1 and 6 — surfaces of section (studies/sections.py)",
    "paper_fig07": "Fig. 7 — C2: finite-time Lyapunov exponents, five methods",
    "paper_fig08": "Fig. 8 — C2: GALIs, five methods",
    "paper_fig09": "Fig. 9 — R2 (3D system): exponents and pair sums",
    "paper_fig10": "Fig. 10 — R2: GALIs",
    "paper_fig11": "Fig. 11 — R3 (FPU-β, N = 8): GALIs",
    "tdheps_variants": "TDHeps: which reading of the paper gives its numbers "
                       "(studies/tdheps_variants.py)",
    "accuracy": "Accuracy against the Taylor reference",
    "work_precision": "Run time against error",
    "stress": "Stress",
    "bench_baselines": "Benchmark: the reference integrators (studies/bench_baselines.py)",
    "bench_chaos_map": "Benchmark: chaos maps (studies/bench_chaos_map.py)",
    "planetary": "Planetary systems: the Kepler tangent map and the Wisdom–Holman error laws "
                 "(studies/planetary.py)",
    "bench_planetary": "Benchmark: MEGNO stability maps of planetary systems against REBOUND "
                       "(studies/bench_planetary.py)",
    "race_planetary": "Benchmark: the full MEGNO map race against REBOUND with multiprocessing "
                      "(studies/race_planetary.py)",
    "two_particle": "The two-particle method the paper left out (studies/two_particle.py)",
    "lattices": "Many-body lattices: the scheme ranking of Danieli et al. 2019 and the speed "
                "targets (studies/lattices.py)",
    "lattices_laws": "Many-body lattices: the chaos laws of disordered lattices "
                     "(studies/lattices.py --part laws)",
    "lattices_kg2d": "Many-body lattices: the 100 × 100 KG lattice run to t = 1e5 "
                     "(studies/lattices.py --part kg2d)",
    "default_step": "The automatic step: its cost, its margin and the held-out cases "
                    "(studies/default_step.py)",
    "map_defaults": "The chaos maps' defaults: scheme and pilot tolerance by classification "
                    "agreement (studies/map_defaults.py)",
    "energy_tolerance": "The accuracy verdict's default energy tolerance "
                        "(studies/energy_tolerance.py)",
}
VERDICT = {True: "holds", False: "**differs**", None: "—"}
#: Studies whose claims the paper makes (the rest are our own questions);
#: a claim's own ``source`` field overrides its study's.
PAPER = [k for k in KNOWN if k in ("table1", "sections") or k.startswith("paper_fig")]


def _cell(text):
    return str(text if text is not None else "").replace("|", "\\|").replace("\n", " ")


def _num(value, digits=2):
    if value in ("", None):
        return "—"
    try:
        return f"{float(value):.{digits}g}"
    except ValueError:
        return value


def _verdict(word):
    return {"": "—", "differs": "**differs**", "differs†": "**differs**†"}.get(word, word)


def _duration(seconds):
    """4321.0 -> '1h12m (4321 s)'; under an hour, '3.7 min (224 s)'."""
    if seconds >= 3600:
        h, m = divmod(round(seconds / 60), 60)
        return f"{h}h{m:02d}m ({seconds:.0f} s)"
    return f"{seconds / 60:.2g} min ({seconds:.0f} s)"


def table1_verdicts(out):
    """Counts of the Table I verdicts (X1 and energy error per row)."""
    path = Path(out) / "table1.csv"
    if not path.exists():
        return None
    words = [r[c] for r in csv.DictReader(path.open()) for c in ("X1_verdict", "energy_verdict")]
    return (len(words), sum(w.startswith("holds") for w in words),
            sum(w.startswith("differs") for w in words), words.count(""))


def load_claims(out):
    """Name -> claims of every ``*.claims.json`` in ``out``, in report order."""
    found = {p.name[: -len(".claims.json")]: json.loads(p.read_text())
             for p in sorted(Path(out).glob("*.claims.json"))}
    order = [k for k in KNOWN if k in found] + sorted(k for k in found if k not in KNOWN)
    return {k: found[k] for k in order}


def table1_section(out):
    """Table I in Markdown: the paper's numbers and ours, row by row."""
    path = Path(out) / "table1.csv"
    if not path.exists():
        return ["*table1.csv is missing: run `python studies/table1.py`.*", ""]
    rows = list(csv.DictReader(path.open()))
    lines = ["| integrator | method | τ | δ | t_end | rel. energy error: paper | ours | "
             "verdict | X1: paper | ours | verdict | CPU: paper | ratio to TM | ours | "
             "ratio to TM | note |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        e_ours = _num(r["energy_error"])
        if r["method"] != "DOP853":
            e_ours += (f" (last decade: {_num(r['energy_error_median_last_decade'])}–"
                       f"{_num(r['energy_error_max_last_decade'])})")
        basis = r.get("cpu_basis") or ("extrapolated" if r["resumed"] == "True" else "measured")
        cpu = _duration(float(r["cpu_s"])) + (f" ({basis})" if basis != "measured" else "")
        # A table written before the compiled DOP853 engine: its DOP853 rows
        # stop short of 1e8, their CPU ratio is projected to 1e8.
        dagger = "†" * (r.get("cpu_projected") == "True")
        lines.append("| " + " | ".join(_cell(c) for c in (
            r["integrator"], r["method"], r["tau"], _num(r["delta"]),
            _num(r["t_end"], 3) + dagger, _num(r["energy_error_paper"]), e_ours,
            _verdict(r["energy_verdict"]), _num(r["X1_paper"]), _num(r["X1"]),
            _verdict(r["X1_verdict"]), r["cpu_paper"], _num(r["cpu_ratio_paper"], 3), cpu,
            _num(r["cpu_ratio"], 3) + dagger, r.get("note", ""))) + " |")
    horizon = max(float(r["t_end"]) for r in rows)
    short = sum(float(r["t_end"]) < horizon for r in rows)
    lines += ["", (f"{len(rows) - short} of {len(rows)} rows ran to t = {horizon:.0e}"
                   + (f"; † {short} stop at t_end, run with SciPy's engine before the "
                      f"compiled one: their CPU ratio is projected to {horizon:.0e}, their "
                      "energy verdict judges the error extrapolated with its growth law, X1 is "
                      "not compared (`table1_cost.md`: what is left to run)" if short
                      else "; nothing is projected") + "."),
              "Verdicts: X1 by the rule "
              "`agrees` (within a factor of 3 of the paper's); the energy error of the "
              "symplectic SBAB2C rows by `in_band` (the paper's value within the band ours "
              "fills over the last decade, median/3 to 3 × max: the error oscillates, so one "
              "value at t = 1e8 is a sample), that of DOP853, which drifts, by `agrees` at "
              "t = 1e8. CPU: `time.process_time()` of each run itself, after a warm-up that "
              "compiles its kernels, summed over the sessions of a run resumed from a "
              "checkpoint as varint measured each (`provenance.cpu_time`); only rows marked "
              "*extrapolated*, resumed before sessions were timed, scale their last session's "
              "CPU time per step to all their steps; DOP853 with the compiled engine "
              "(`engine=\"compiled\"`, SciPy's method bit for bit). The machine has 2 cores "
              "shared with other jobs, so absolute times vary between sessions: compare the "
              "ratios to the TM row with τ = 0.05 (the paper's: AMD Athlon 1 GHz).", ""]
    if (Path(out) / "table1_energy.png").exists():
        lines += ["![Table I: energy error against time](table1_energy.png)", ""]
    return lines


def source(name, item):
    """"paper" or "own": whose claim it is."""
    return item.get("source") or ("paper" if name in PAPER else "own")


def short_horizon(item):
    """True when the claim was checked only to a horizon shorter than the
    paper's."""
    return "checked_to" in item and item["checked_to"] < item["horizon"] * (1 - 1e-9)


def verdict_cell(item):
    word = VERDICT[item.get("holds")]
    if item.get("holds") is not None and short_horizon(item):
        word += f" (to {item['checked_to']:.0e}; paper {item['horizon']:.0e})"
    return word


def rules_cell(item):
    """The rules that decided a claim, each with its window."""
    parts = []
    for r in item.get("rules", []):
        w = r.get("window")
        text = r["rule"] + (f" [{w[0]:.2g}–{w[1]:.2g}]" if w else "")
        if text not in parts:
            parts.append(text)
    return "; ".join(parts) if parts else "—"


def claims_section(name, items, out):
    """One section: each figure, then the claims it supports."""
    lines = [f"## {KNOWN.get(name, name)}", "", f"*`{name}.claims.json`*", ""]
    by_figure = {}
    for item in items:
        by_figure.setdefault(item.get("figure"), []).append(item)
    for fig, group in by_figure.items():
        if fig and (Path(out) / fig).exists():
            lines += [f"![{fig}]({fig})", ""]
        elif fig:
            lines += [f"*figure {fig} is missing*", ""]
        lines += ["| claim | paper | ours | verdict | rules [window] | note |",
                  "|---|---|---|---|---|---|"]
        for item in group:
            own = " *(own check)*" if source(name, item) == "own" and name in PAPER else ""
            lines.append("| " + _cell(item.get("claim")) + own + " | "
                         + " | ".join(_cell(item.get(k)) for k in ("paper", "ours"))
                         + f" | {verdict_cell(item)} | {_cell(rules_cell(item))} | "
                         f"{_cell(item.get('note'))} |")
        lines.append("")
    return lines


def rules_section():
    """The rules of :mod:`studies.claims`, with their tolerances."""
    lines = ["## How claims are judged", "",
             "One rule per kind of claim (`studies/claims.py`), the same for every figure and "
             "study; each claim below names the rules it was judged by and the window of "
             "times they looked at. A verdict reached with a run shorter than the paper's "
             "says how far it was checked. A claim that differs carries its explanation, or "
             "the word *unexplained*.", "",
             "| rule | tolerance | why |", "|---|---|---|"]
    for name, (_, tolerance, why) in RULES.items():
        lines.append(f"| `{name}` | {_cell(tolerance)} | {_cell(why)} |")
    return lines + [""]


def runs_section(out):
    """The stored runs of the paper's studies with their cost, how the CPU
    time was obtained and the code that made them."""
    metas = sorted((Path(out) / "runs").glob("*.json"))
    if not metas:
        return []
    lines = ["## The runs behind Table I and the figures", "",
             "Stored in `runs/` (result `.npz` with provenance, sidecar `.json` with CPU "
             "time). CPU: `time.process_time()` over all the sessions of a run, on a shared "
             "machine; *extrapolated* where a run was resumed before sessions were timed "
             "(its last session's CPU per step times all its steps). Code: the digest of "
             "varint's sources that made the run (*not recorded* for runs stored before "
             "it was; `PROVENANCE.json` names the commit that stored each file).", "",
             "| run | CPU s | CPU | wall s | code |", "|---|---|---|---|---|"]
    for p in metas:
        m = json.loads(p.read_text())
        basis = m.get("cpu_basis") or ("extrapolated" if m.get("resumed") else "measured")
        code = (m.get("code") or {}).get("source")
        lines.append(f"| `{p.stem}` | {m['cpu']:.4g} | {basis.split(':')[0]} | "
                     f"{m['wall']:.4g} | {code[:12] if code else 'not recorded'} |")
    return lines + [""]


def _shape(claim):
    """A claim's wording with its numbers blanked."""
    return re.sub(r"[-+−]?\d[\d.e+−-]*", "#", claim)


#: The paper's DOP853 runs beyond Table I and the paper's horizons.
_PAPER_DOP853 = (("lyapunov", "C1", 1e8), ("lyapunov", "C2", 1e8), ("gali", "C2", 1e8),
                 ("lyapunov", "R2", 1e6), ("gali", "R2", 1e6), ("gali", "R3", 1e6))


def _dop853_horizons(out):
    """Where the stored DOP853 runs of C1, C2, R2 and R3 end, against the
    paper's horizons: read from the run files, so the report never says a
    run reached a horizon it did not."""
    parts = []
    for kind, orbit, paper in _PAPER_DOP853:
        tau = 0.02 if orbit == "R3" else PAPER_TAU
        t = longest_stored(out, kind, orbit, "dop853", tau, delta=PAPER_DELTA)
        name = f"DOP853 {'spectrum' if kind == 'lyapunov' else 'GALIs'} of {orbit}"
        parts.append(f"{name} to {t:.0e}" + ("" if t is not None and t >= paper
                                             else f", not the paper's {paper:.0e}")
                     if t is not None else f"{name}: not stored")
    return "; ".join(parts)


def changed_section(claims, out):
    """Every claim whose verdict differs from the one stored before this
    round (``verdicts_previous.json``), with its note: why it changed."""
    path = Path(out) / "verdicts_previous.json"
    if not path.exists():
        return []
    before = json.loads(path.read_text())
    lines = ["## Verdicts changed since the previous round", "",
             f"Against the verdicts stored at commit `{before['commit']}` "
             f"(`verdicts_previous.json`): longer runs ({_dop853_horizons(out)}), the "
             "statistical criterion for chaotic orbits and the stated margins.", "",
             "| study | claim | before | now | ours now | why |", "|---|---|---|---|---|---|"]
    n, new = 0, {}
    for name, items in claims.items():
        old = {i["claim"]: i for i in before["claims"].get(name, [])}
        # A claim whose wording names its window or horizon is the same
        # claim with other numbers.
        loose = {_shape(c): i for c, i in old.items()}
        for item in items:
            prev = old.get(item["claim"]) or loose.get(_shape(item["claim"]))
            if prev is None:
                new[name] = new.get(name, 0) + 1
                continue
            if prev["holds"] == item.get("holds"):
                continue
            n += 1
            why = [item.get("note") or ""]
            if prev.get("checked_to") != item.get("checked_to") and item.get("checked_to"):
                was = prev.get("checked_to")
                why.insert(0, f"checked to t = {item['checked_to']:.0e} (before: "
                              + (f"{was:.0e}" if was else "its full horizon") + ")")
            lines.append(f"| {name} | {_cell(item['claim'])} | {VERDICT[prev['holds']]} | "
                         f"{verdict_cell(item)} | {_cell(item.get('ours'))} | "
                         f"{_cell('; '.join(w for w in why if w))} |")
    if not n:
        lines.append("| — | no verdict changed | | | | |")
    if new:
        lines += ["", "Claims new since then (or reworded): " + ", ".join(
            f"{name} {count}" for name, count in new.items()) + "."]
    return lines + [""]


def _counts(items):
    verdicts = [i.get("holds") for i in items]
    return (len(items), verdicts.count(True), sum(i.get("holds") is True and short_horizon(i)
                                                  for i in items),
            verdicts.count(False), verdicts.count(None))


def summary(claims, out):
    """Two tables: the paper's claims, and varint's own checks."""
    head = ["| study | claims | hold | of which checked to a shorter horizon | differ | "
            "not compared |", "|---|---|---|---|---|---|"]
    lines = ["### The paper's claims", ""] + head
    total = []
    for name, items in claims.items():
        mine = [i for i in items if source(name, i) == "paper"]
        if mine:
            total += mine
            lines.append(f"| {KNOWN.get(name, name)} | " + " | ".join(map(str, _counts(mine)))
                         + " |")
    lines.append("| **all the paper's claims (text, figures)** | "
                 + " | ".join(f"**{v}**" for v in _counts(total)) + " |")
    counts = table1_verdicts(out)
    if counts:
        lines += ["", "Table I cell by cell (X1 and energy error of each row, not in the total "
                  "above): {} cells, {} hold, {} differ, {} not compared.".format(*counts)]
    lines += ["", "### varint's own checks", ""] + head
    total = []
    for name, items in claims.items():
        mine = [i for i in items if source(name, i) == "own"]
        if mine:
            total += mine
            lines.append(f"| {KNOWN.get(name, name)} | " + " | ".join(map(str, _counts(mine)))
                         + " |")
    lines.append("| **all own checks** | " + " | ".join(f"**{v}**" for v in _counts(total))
                 + " |")
    return lines + [""]


def build(out):
    """The text of REPORT.md for the results in ``out``."""
    claims = load_claims(out)
    lines = ["# Skokos & Gerlach (2010) re-measured", "",
             "Generated by `python studies/report.py` from the result files in this "
             "directory; do not edit by hand. The paper: Ch. Skokos & E. Gerlach, "
             "*Numerical integration of variational equations*, Phys. Rev. E 82, 036704 "
             "(2010). Its setups and claims are set against ours below, claim by claim.", "",
             "Verdicts: *holds* — our number or fitted law agrees with the paper's by the rule "
             "of its kind (below); ***differs*** — it does not (the note says why, or "
             "*unexplained*); *—* — nothing to compare (a horizon we do not reach, or a "
             "measurement of ours only).", "", "## Summary", ""]
    lines += summary(claims, out)
    lines += rules_section()
    missing = [k for k in PAPER if k not in claims]
    if missing:
        lines += ["Missing: " + ", ".join(f"`{k}.claims.json`" for k in missing), ""]
    lines += changed_section(claims, out)
    lines += ["## Table I — R1 to t = 1e8", ""] + table1_section(out)
    for name, items in claims.items():
        lines += claims_section(name, items, out)
    lines += runs_section(out)
    return "\n".join(lines)


def main(argv=None):
    args = parse_args(__doc__.split("\n\n")[0], argv)
    text = build(args.out)
    path = args.out / "REPORT.md"
    path.write_text(text)
    print(f"wrote {path}")
    return {"path": path, "text": text}


if __name__ == "__main__":
    main()
