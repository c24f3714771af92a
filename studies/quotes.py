"""Every measured number of README.md and the documentation, rendered from a
result stored under ``studies/results/``.

A measured number is never typed: README.md writes it as

    <!--q:NAME-->TEXT<!--/q-->

and the documentation's reStructuredText as the role ``:q:`NAME```
(rendered when the site is built, ``docs/_ext/varint_docs.py``). NAME is a
key of :data:`QUOTES`, a function of the stored results (:class:`Results`)
that returns the text. ``python studies/quotes.py`` rewrites every TEXT of
README.md from the stored results; ``tests/studies/test_quotes.py`` fails
when a marked TEXT differs from what its source gives, when a NAME has no
source, or when README.md or a documentation page shows a number that
looks measured (a time, a rate, a ratio, a percentage, a number with
decimals) outside a quote, a code block or a parameter (``τ = 0.05``).

Ratios are quoted with their spread over the repeats of the run that
measured them (smallest–largest of the ratio within each turn) where the
run stored it, and every table states the load of the machine during the
run; a figure that could not be re-measured says so in its row.

Usage: ``python studies/quotes.py [--check]``
"""

from __future__ import annotations

import csv
import json
import contextlib
import re
import sys
from functools import cached_property
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from studies.common import RESULTS  # noqa: E402

__all__ = ["QUOTES", "Results", "render", "fill", "MARKER", "stale", "unsourced", "README",
           "ROLE", "rst_prose", "docs_pages", "ALLOWED"]

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: ``<!--q:NAME-->TEXT<!--/q-->`` (TEXT may span lines: a table).
MARKER = re.compile(r"<!--q:([\w.-]+)-->(.*?)<!--/q-->", re.S)


class Results:
    """The stored results, read once: ``R.json("table1")``,
    ``R.csv("table1")``, ``R.claims("paper_fig05")``, ``R.run(key)`` (a
    stored run's sidecar)."""

    def __init__(self, folder=RESULTS):
        self.folder = Path(folder)
        self._cache = {}

    def _read(self, name, reader):
        if name not in self._cache:
            path = self.folder / name
            if not path.exists():
                raise FileNotFoundError(f"no stored result {path}")
            self._cache[name] = reader(path)
        return self._cache[name]

    def json(self, name):
        return self._read(f"{name}.json", lambda p: json.loads(p.read_text()))

    def csv(self, name):
        return self._read(f"{name}.csv", lambda p: list(csv.DictReader(p.open())))

    def claims(self, name):
        return self.json(f"{name}.claims")

    def run(self, key):
        return self.json(f"runs/{key}")

    @cached_property
    def all_claims(self):
        return {p.name[:-len(".claims.json")]: json.loads(p.read_text())
                for p in sorted(self.folder.glob("*.claims.json"))}


# -- formatting ------------------------------------------------------------------

def ratio(x):
    """A ratio as README writes it: three significant digits, whole numbers
    from 100 on."""
    return f"{x:.0f}" if x >= 100 else f"{x:.3g}"


def spread(lo_hi):
    """'1.9–2.1' from (lo, hi), or '' without a spread."""
    if not lo_hi:
        return ""
    lo, hi = lo_hi
    return f"{ratio(lo)}–{ratio(hi)}"


def sci(x, digits=2):
    """1.57e-7 style (no zero padding in the exponent)."""
    m, e = f"{x:.{digits - 1}e}".split("e")
    return f"{m}e{int(e)}"


def signed(x, digits=2):
    """sci() with a minus sign (−) for a negative number."""
    return ("−" if x < 0 else "") + sci(abs(x), digits)


def power(x):
    """1e-7 style for a power of ten (a tolerance)."""
    return f"{x:.0e}".replace("e-0", "e-").replace("e+0", "e")


def thousands(x):
    """16 682: a thin space between groups of three digits, as README."""
    return f"{x:,.0f}".replace(",", " ")


QUOTES = {}


def quote(name):
    """Register a function of :class:`Results` as the quote ``name``."""
    def register(fn):
        QUOTES[name] = fn
        return fn
    return register


def render(name, results=None):
    """The text of the quote ``name`` from the stored results."""
    if name not in QUOTES:
        raise KeyError(f"quote {name!r} has no stored source (studies/quotes.py QUOTES)")
    return QUOTES[name](results or Results())


def fill(text, results=None):
    """``text`` with every marked quote rewritten from the stored results."""
    results = results or Results()
    return MARKER.sub(lambda m: f"<!--q:{m[1]}-->{render(m[1], results)}<!--/q-->", text)


def stale(text, results=None):
    """(name, written, rendered) of every marked quote whose text is not
    what its source gives ("no stored source: …" where the name or the data
    it reads is missing)."""
    results = results or Results()
    out = []
    for m in MARKER.finditer(text):
        try:
            now = render(m[1], results)
        except (KeyError, LookupError, FileNotFoundError, TypeError, ValueError) as exc:
            now = f"no stored source: {type(exc).__name__}: {exc}"
        if now != m[2]:
            out.append((m[1], m[2], now))
    return out


# -- numbers outside quotes ----------------------------------------------------------

#: What a measured number looks like: a time or a rate with its unit, a
#: ratio (5.5×), a percentage, or a number with decimals or an exponent
#: (but not a bare power of ten, 1e-8: a tolerance, a default, a scale).
_MEASURED = re.compile(
    r"(?<![\w.^/])(\d[\d  ]*(?:\.\d+)?\s?(?:ns|µs|ms|s|min|h)\b(?!\w)"
    r"|\d+(?:\.\d+)?\s?×(?!\s?\d)"
    r"|\d+(?:\.\d+)?\s?%"
    r"|\d+\.\d+(?:e[-+−]?\d+)?"
    r"|(?!1e)\d+e[-+−]?\d+)")
#: A number right after one of these is a parameter or a definition, not a
#: measurement ("τ = 0.05", "E = 1/8", "t ≈ 1e4" as a time on an axis).
_PARAMETER = re.compile(
    r"(?:\b(?:Python|τ|Δt|t|t_end|δ|d0|d_max|H|E|K|β|W|ε|tol|rtol|atol|N|n|k|x|y|p_x|p_y|q|g|α|"
    r"beta|tau|seeds?|sites|grid|x0|level|radius|threshold|energy_tol|target)\s*"
    r"(?:=|≈|≤|<|>|≥|~)\s*(?:[−-]?[\d.e−-]+(?:,| to| and| …)\s*)*[−-]?)$")
#: Numbers that are not measurements though they look like ones, each with
#: why: exact phrases of README.md or a documentation page.
ALLOWED = (
    "within 0.2 of the",   # the tolerance of tests/test_schemes.py's order check
    "target is 10 min",    # the target for the 2D KG run, not a measurement
    "Λ ∝ t^−0.25 (weak) and t^−0.3",  # the lattice papers' laws, cited on the next lines
)


def unsourced(text, allowed=ALLOWED):
    """Numbers of ``text`` that look measured and stand outside quotes,
    code and parameters: (line number, the line) of each. ``allowed`` are
    exact substrings (a paper's own number in a sentence that names it)."""
    text = MARKER.sub(lambda m: " " * len(m[0]), text)
    text = re.sub(r"```.*?```", lambda m: "\n" * m[0].count("\n"), text, flags=re.S)
    text = re.sub(r"`[^`]*`", lambda m: re.sub(r"[^\n]", " ", m[0]), text)
    text = re.sub(r"<!--.*?-->", lambda m: "\n" * m[0].count("\n"), text, flags=re.S)
    found = []
    for i, line in enumerate(text.splitlines(), 1):
        for m in _MEASURED.finditer(line):
            if _PARAMETER.search(line[:m.start()]) or any(a in line for a in allowed):
                continue
            found.append((i, line.strip()))
            break
    return found


# -- where a figure was measured ------------------------------------------------------

def code_name(code):
    """A code record in a table cell: the commit it ran from (and "+ edits"
    where the sources differed from it), else its source digest."""
    if not isinstance(code, dict):
        return "code not recorded"
    if code.get("commit"):
        return f"commit {code['commit'][:7]}" + (" + edits" if code.get("modified") else "")
    return f"sources {code['source'][:7]}"


def measured_in(data, study):
    """'study, load a → b' from a stored JSON's ``_provenance`` (or the
    load it recorded itself), and 'code not recorded' for results stored
    before code identity was."""
    prov = data.get("_provenance")
    if prov:
        return (f"`{study}`, load {prov['machine']['load']:.1f} → {prov['load_end']:.1f}, "
                f"{code_name(prov['code'])}")
    load = data.get("load_average")
    load = (f", load {load[0]:.1f} → {load[1]:.1f}" if isinstance(load, list)
            else f", load {load:.1f}" if isinstance(load, (int, float)) else "")
    return f"`{study}`, an earlier run{load}, code not recorded"


def _peers_measured(R, case):
    """Where bench_peers measured ``case``: this case's own record when the
    run was merged (``--merge``), else the run's."""
    d = R.json("bench_peers")
    m = d.get("measured", {}).get(case)
    if isinstance(m, dict) and isinstance(m.get("code"), dict):
        return (f"`bench_peers --cases {case}`, load {m['load'][0]:.1f} → {m['load'][1]:.1f}, "
                f"{code_name(m['code'])}")
    return measured_in(d, "bench_peers")


def _turn_spread(slow, fast):
    """The spread of ``slow``'s time over ``fast``'s from two rows' per-turn
    times, leaving out the first turn when there are three or more: a
    chaos map's first call on the full grid may still compile its lane
    kernel (bench_peers' warm-up runs two orbits), which the minimum leaves
    out too."""
    a, b = slow.get("turn_seconds"), fast.get("turn_seconds")
    if not a or not b:
        return None
    if len(a) > 2:
        a, b = a[1:], b[1:]
    r = [x / y for x, y in zip(a, b, strict=True)]
    return [min(r), max(r)]


def _against_heyoka(value):
    """A ratio heyoka time / varint time from one run, saying who is faster."""
    return (f"{ratio(value)}× faster (one run)" if value >= 1
            else f"{ratio(value)}× (heyoka faster; one run)")


def _frontier_rows(R):
    """The high-accuracy race (``studies/frontier.py``): orbit and one
    tangent vector to t = 1e3 at each target error, varint through a
    prepared run (its cheapest scheme there) against heyoka's scalar
    Taylor integrator at the tolerance that reaches it."""
    fr = R.json("frontier")
    where = measured_in(fr, "frontier")
    rows = []
    floors = {(f["orbit"], f["contender"]): f["floor"] for f in fr["floors"]}
    for r in fr["ratios"]:
        what = (f"{r['orbit']}, orbit + one vector to t = {power(fr['t_end'])}, global error "
                f"{sci(r['target'])}, 1 thread (CPU time)")
        if r["cpu_prepared_seconds"] is None:
            continue
        scheme, _, level = r["cpu_prepared_scheme"].removesuffix(" prepared").partition("+")
        # The suffixes of studies/frontier.py's labels, as the keyword a user passes.
        scheme += {"": "", "c": ", compensated", "co": ', compensated="orbit"',
                   "cs": ', compensated="step"'}[level]
        mine = f"{1e3 * r['cpu_prepared_seconds']:.2f} ms ({scheme}, prepared)"
        if r["cpu_heyoka_seconds"] is None:
            rows.append((what, mine, f"heyoka cannot reach it (its floor "
                         f"{sci(floors[(r['orbit'], 'heyoka')])})", "—", where))
            continue
        rows.append((what, mine, f"heyoka's Taylor method at the tolerance that reaches it, "
                     f"{1e3 * r['cpu_heyoka_seconds']:.2f} ms",
                     _against_heyoka(r["cpu_ratio_prepared"]), where))
    return rows


def _singular_map_rows(R):
    """FLI maps of potentials with a near-singular centre with every
    default (``studies/map_steps.py --part log``), against heyoka batch 8
    at its cheapest tolerance that reaches the same agreement."""
    names = {"cr3bp": "restricted three-body problem (Sun–Jupiter)",
             "core": "cored logarithmic potential, R_c = 0.03"}
    rows = []
    for name, label in names.items():
        ms = _newest_map_run(R, name)
        where = measured_in(ms, "map_steps --quick --part log")
        mine = [r for r in ms["log"]["rows"] if r["map"] == name]
        v = next((r for r in mine if r["contender"] == "varint defaults"), None)
        if v is None:
            continue
        hy = min((r for r in mine if r["contender"].startswith("heyoka")
                  and r["agreement"] >= v["agreement"]), key=lambda r: r["seconds"])
        # A grid whose reference is almost all one verdict cannot judge a
        # map that calls every orbit the same (map_steps.judging).
        judged = ("" if v.get("judging", True) else
                  f"; the reference calls {100 * v['reference_chaotic']:.0f} % chaotic, so agreement "
                  "cannot judge")
        rows.append((f"FLI map of the {label}, {v['orbits']} orbits, t = {v['t_end']:g}, "
                     f"1 thread, defaults ({v['method']}, {v['steps_per_orbit']:.0f} steps "
                     "per orbit)", f"{v['seconds']:.3f} s, {100 * v['agreement']:.1f} % "
                     f"agreement{judged}", f"heyoka batch 8 at its cheapest tolerance as good, "
                     f"{hy['seconds']:.3f} s", _against_heyoka(hy["seconds"] / v["seconds"]),
                     where))
    return rows


def _newest_map_run(R, name):
    """The newest stored ``map_steps --quick --part log`` run of map
    ``name``: the run of both maps (``map_steps_quick_log``) or of that map
    alone (``map_steps_quick_<name>_log``), whichever was made last."""
    runs = [R.json("map_steps_quick_log")]
    with contextlib.suppress(FileNotFoundError):
        runs.append(R.json(f"map_steps_quick_{name}_log"))
    return max(runs, key=lambda d: d["_provenance"]["created"])


def _ratio_cell(value, lo_hi, faster=False):
    text = ratio(value) + ("× faster" if faster else "")
    return text + (f" ({spread(lo_hi)})" if lo_hi else " (one run)")


# -- prose quotes ---------------------------------------------------------------------

@quote("step_taus")
def _step_taus(R):
    by = {}
    for r in R.json("default_step")["costs"]:
        by.setdefault(f"{r['tau']:.3g}", []).append(r["orbit"])
    parts = [f"{tau} ({', '.join(orbits)})" for tau, orbits in
             sorted(by.items(), key=lambda kv: -len(kv[1]))]
    return "τ = " + " and ".join(parts)


@quote("step_work")
def _step_work(R):
    w = [r["work_ratio_10000"] for r in R.json("default_step")["costs"]]
    return f"{min(w):.2f}–{max(w):.2f}"


def _map_choice(R, ind):
    return R.json("map_defaults")["choice"][ind]


@quote("map_choice")
def _map_choice_text(R):
    m, s = _map_choice(R, "megno"), _map_choice(R, "sali")
    f = _map_choice(R, "fli")
    same = (f["scheme"], f["tolerance"]) == (m["scheme"], m["tolerance"])
    text = (f"{m['scheme']} to {power(m['tolerance'])} for MEGNO" + (" and FLI" if same else "")
            + f", τ ≈ {m['tau']:.2g} there")
    if not same:
        text += f"; {f['scheme']} to {power(f['tolerance'])} for FLI (τ ≈ {f['tau']:.2g})"
    return text + (f"; {s['scheme']} to {power(s['tolerance'])} for SALI "
                   f"(τ = {s['tau']:.2g})")


@quote("map_steps_orbit")
def _map_steps_orbit(R):
    """tau="orbit" against the defaults (studies/map_steps.py, race): steps,
    seconds and agreement on each map of the full run."""
    race = R.json("map_steps_race")["race"]
    steps = {(r["map"], r["contender"]): r["steps"] for r in race["rows"] if "steps" in r}
    orbits = {r["map"]: r["orbits"] for r in race["rows"]}
    parts = []
    for name, what in (("core", "the small-core map"), ("cr3bp", "the restricted three-body map")):
        s = race["summary"][name]
        ours, per = s["varint defaults"], s["varint, tau='orbit'"]
        gain = steps[name, "varint defaults"] / steps[name, "varint, tau='orbit'"]
        parts.append(
            f"on {what} ({orbits[name]} orbits) {gain:.1f} times fewer steps and a "
            f"{ours['varint_seconds'] / per['varint_seconds']:.1f} times shorter map, classifying "
            f"{per['varint_agreement']:.1%} of the orbits as a tight reference does against the "
            f"defaults' {ours['varint_agreement']:.1%}")
    load = max(race["load"][0], race["load_end"][0])
    return "; ".join(parts) + f" (one thread each, machine load up to {load:.0f})"


def _chaos_row(R, method):
    return next(r for r in R.json("bench_chaos_map")["rows"] if r["method"].startswith(method))


@quote("chaos_map_bench")
def _chaos_map_bench(R):
    d = R.json("bench_chaos_map")
    early, none = _chaos_row(R, "varint, early"), _chaos_row(R, "varint, no early")
    dask, hy = _chaos_row(R, "varint on Dask"), _chaos_row(R, "Python loop over heyoka")
    py = _chaos_row(R, "Python loop over pynamicalsys")
    gain = [r["speedup_of_varint"] for r in (hy, py)]
    return (f"{d['grid']} × {d['grid']} map of the paper's section (t = {d['t_end']:.0e}, "
            f"τ = 0.05; {thousands(d['orbits'])} allowed orbits): {early['seconds']:.1f} s with "
            f"early stopping ({thousands(early['orbits_per_second'])} orbits/s) and "
            f"{none['seconds']:.1f} s without, on the 2 cores of the development machine "
            f"(load {d['load_average']:.1f}), {dask['seconds']:.1f} s on a local Dask cluster of "
            f"2 workers (bitwise the same values), against {hy['orbits_per_second']:.1f} "
            f"orbits/s for a Python loop over heyoka and {py['orbits_per_second']:.1f} for one "
            f"over {py['method'].split('over ')[1].split(' (')[0]}: {thousands(min(gain))}–"
            f"{thousands(max(gain))}× more orbits per second").replace("e+0", "e")


@quote("blocks_gain")
def _blocks_gain(R):
    rows = {(r["config"], r["k"]): r for r in R.json("bench_baselines")["methods"]}
    gains = []
    for k in {r["k"] for r in R.json("bench_baselines")["methods"]}:
        for block, restart in (("cvode 1e-10 (default: 1000 tu, exact Jacobian)",
                                "cvode 1e-10, restart every tau"),
                               ("taylor double (default: blocks of 50 tu)",
                                "taylor double, restart every tau")):
            gains.append(rows[restart, k]["ms_per_tu"] / rows[block, k]["ms_per_tu"])
    return f"{ratio(min(gains))}–{ratio(max(gains))}×"


@quote("reference_valid")
def _reference_valid(R):
    v = R.json("accuracy")["valid_until"]
    long = max(v.values())
    short = {o: t for o, t in v.items() if t < long and o != "C1"}
    return (f"to t = {power(long)}" + "".join(f" ({power(t)} for {o})" for o, t in short.items())
            + f" and, on the chaotic C1, valid to t ≈ {v['C1']:.0f}")


def _level_law(R, method):
    """(coefficient, power) of the TDH level on R1: level ≈ c τ^p fitted to
    the stored departures (least squares in log–log)."""
    import numpy as np

    rows = [d for d in R.json("accuracy")["departure"] if d["method"] == method and d["level"]]
    tau = np.log([d["tau"] for d in rows])
    level = np.log([d["level"] for d in rows])
    p, logc = np.polyfit(tau, level, 1)
    return float(np.exp(logc)), float(p)


@quote("tdh_level_laws")
def _tdh_level_laws(R):
    (c1, p1), (c2, p2) = _level_law(R, "tdhcc"), _level_law(R, "tdheps")
    return f"{c1:.2g} τ^{p1:.1f} and {c2:.2g} τ^{p2:.1f}"


@quote("tdh_departure_times")
def _tdh_departure_times(R):
    t = {d["method"]: d["t_x1"] for d in R.json("accuracy")["departure"]
         if d["tau"] == 0.05 and d["method"] in ("tdhcc", "tdheps")}
    return f"t ≈ {sci(t['tdhcc'], 1)} and {sci(t['tdheps'], 1)}"


def _wp_claim(R, start):
    return next(c for c in R.claims("work_precision") if c["claim"].startswith(start))


@quote("wp_taylor_only")
def _wp_taylor_only(R):
    text = _wp_claim(R, "tangent_R1: where a baseline beats TM by wall time")["ours"]
    return "below " + text.split("Taylor at errors ")[1].split("…")[0]


@quote("wp_taylor_ratio")
def _wp_taylor_ratio(R):
    text = _wp_claim(R, "tangent_R1: wall time of the baselines")["ours"]
    return text.split("Taylor ")[1].split(";")[0].replace("×", "") + " times"


@quote("wp_others_ratio")
def _wp_others_ratio(R):
    text = _wp_claim(R, "tangent_R1: wall time of the baselines")["ours"]
    return "; ".join(part.strip().replace("×", " times") for part in text.split(";")[1:])


def _tp(R):
    return R.json("two_particle")


@quote("tp_slopes")
def _tp_slopes(R):
    laws = _tp(R)["error_laws"].values()
    cur = [v["curvature_slope"] for v in laws]
    rnd = [v["rounding_slope"] for v in laws]
    return (f"fitted slopes {min(cur):.2f}–{max(cur):.2f}", f"slopes {max(rnd):.2f} to "
            f"{min(rnd):.2f}")


@quote("tp_curvature")
def _tp_curvature(R):
    return _tp_slopes(R)[0]


@quote("tp_rounding")
def _tp_rounding(R):
    return _tp_slopes(R)[1].replace("-", "−")


@quote("tp_best")
def _tp_best(R):
    laws = _tp(R)["error_laws"]
    r1, r3, c1 = laws["R1 tau=0.025"], laws["R3 tau=0.025"], laws["C1 tau=0.025"]
    return (f"{sci(r1['best_own'])} on R1 against the TM method's whole error of "
            f"{sci(r1['tm_error'])} ({ratio(r1['best_own'] / r1['tm_error'])}×), "
            f"{sci(r3['best_own'])} on R3 against {sci(r3['tm_error'])} "
            f"({ratio(r3['best_own'] / r3['tm_error'])}×); on C1 ({sci(c1['best_own'])}) it "
            f"hides under the integration error both methods share ({sci(c1['tm_error'])} at "
            "t = 300, amplified as e^{λt})")


@quote("tp_in_time")
def _tp_in_time(R):
    d = _tp(R)["in_time"]
    keys = sorted(d, key=float, reverse=True)
    biases = ", ".join(signed(d[k]["bias_level"]) for k in keys)
    timed = [k for k in keys if d[k]["t_10pct"]]
    return (f"{biases} over the last decade for d0 = " + ", ".join(power(float(k)) for k in keys)
            + "; X1 is 10 % wrong from t ≈ " + " and ".join(sci(d[k]["t_10pct"]) for k in timed)
            + (f" for the first {len(timed)}" if len(timed) < len(keys) else "")
            + "".join(f" (not within the run for d0 = {power(float(k))})" for k in keys
                      if not d[k]["t_10pct"]))


@quote("tp_gali")
def _tp_gali(R):
    g = _tp(R)["gali"]
    dep, tp, tm = g["two_particle_departs"], g["two_particle_last"], g["tm_last"]
    return (f"t ≈ {sci(dep['3'])} and {sci(dep['4'])} (a factor 10 apart to the end); at "
            f"t = 1e5 they are {sci(tp['3'])} and {sci(tp['4'])} against {sci(tm['3'])} and "
            f"{sci(tm['4'])}")


@quote("roundoff_floor")
def _roundoff_floor(R):
    f = R.json("roundoff_floor")["varint_floor"]
    return f"GALI_3 ≈ {sci(f['3'])}, GALI_4 ≈ {sci(f['4'])}"


@quote("tp_cost")
def _tp_cost(R):
    parts = []
    for c in _tp(R)["cost"]:
        tm, tp = c["tm"], c["two-particle"]
        if tm is None or tp is None:
            who = "the two-particle method" if tp is None else "the TM method"
            parts.append(f"on {c['orbit']} {who} did not reach {power(c['target'])} in the scan")
            continue
        parts.append(f"{ratio(tp['cpu_seconds_per_time'] / tm['cpu_seconds_per_time'])}× the TM "
                     f"method's on {c['orbit']} for an X1 error ≤ {power(c['target'])} "
                     f"(force evaluations per unit time {tp['forces_per_time']:.0f} against "
                     f"{tm['forces_per_time']:.0f})")
    return "; ".join(parts) + " (one run)"


# -- the TDH methods --------------------------------------------------------------------

@quote("tdh_costs")
def _tdh_costs(R):
    d = R.json("bench_tdh")
    by = {r["method"]: r for r in d["rows"] if r["orbit"] == "R1" and r["k"] == 4}

    def cell(name):
        r = by[name]
        return f"{ratio(r['vs_tm'])}×" + (f" ({spread(r['spread'])})" if r.get("spread") else "")

    t1 = {r["method"]: r for r in R.json("table1")["rows"] if r["tau"] == 0.05}
    return (f"TDHcc {cell('tdhcc')} the TM method per interval (QR every interval for both), "
            f"TDHeps {cell('tdheps')}, TDHes {cell('tdhes analytic')} with the analytic "
            f"transformation and {cell('tdhes')} with LAPACK (Hénon–Heiles R1, k = 4, "
            f"{measured_in(d, 'bench_tdh')}); in the runs of Table I to 1e8: TDHcc "
            + ", TDHes ".join(f"{t1[m]['cpu_ratio']:.2f}×" for m in ("TDHcc", "TDHes"))
            + f", TDHeps {t1['TDHeps']['cpu_ratio']:.2f}× (the paper: "
            + "–".join(f"{v:.2f}" for v in sorted(
                {t1[m]["cpu_ratio_paper"] for m in ("TDHcc", "TDHes", "TDHeps")})[::2]) + "×)")


def _departure(R, method, tau=0.05):
    return next(d for d in R.json("accuracy")["departure"]
                if d["method"] == method and d["tau"] == tau)


@quote("tdh_levels")
def _tdh_levels(R):
    (c1, p1), (c2, p2) = _level_law(R, "tdhcc"), _level_law(R, "tdheps")
    cc = _departure(R, "tdhcc")
    paper = next(r for r in R.json("table1")["rows"] if r["method"] == "TDHcc"
                 and r["tau"] == 0.05)["X1_paper"]
    return (f"≈ {c1:.2g} τ^{p1:.1f} for TDHcc and TDHes ({sci(cc['level'])} at τ = 0.05, the "
            f"paper's Table I value {sci(paper)}) and ≈ {c2:.2g} τ^{p2:.1f} for TDHeps, which "
            f"departs at t ≈ {sci(_departure(R, 'tdheps')['t_x1'], 1)} for τ = 0.05")


def _tdheps_ratios(R):
    return [r["X1"] / r["X1_paper"] for r in R.json("table1")["rows"] if r["method"] == "TDHeps"]


@quote("tdheps_paper_ratio")
def _tdheps_paper_ratio(R):
    v = _tdheps_ratios(R)
    return f"{min(v):.1f}–{max(v):.1f}×"


def _variants(R):
    return R.csv("tdheps_variants")


@quote("tdheps_energy")
def _tdheps_energy(R):
    found = {}
    for c in R.claims("tdheps_variants"):
        m = re.search(r"τ = ([\d.]+): Table I's TDHeps energy error", c["claim"])
        if m:
            half, full = re.findall(r"([\d.]+e[-+]\d+) at Δt", c["ours"])
            found[m[1]] = (float(half), float(full))
    taus = sorted(found, key=float)
    return (f"largest error {', '.join(sci(found[t][1]) for t in taus)}), not at the caption's "
            f"Δt = τ/2 ({', '.join(sci(found[t][0]) for t in taus)})")


@quote("tdheps_paper_energy")
def _tdheps_paper_energy(R):
    rows = [r for r in R.json("table1")["rows"] if r["method"] == "TDHeps" and r["tau"] > 0.05]
    return ", ".join(power(r["energy_error_paper"]) if f"{r['energy_error_paper']:.0e}"
                     .startswith("1e") else sci(r["energy_error_paper"], 1) for r in rows)


@quote("tdheps_levels_full")
def _tdheps_levels_full(R):
    rows = [r for r in _variants(R) if r["orbit"] == "R1"]
    full = [float(r["ratio"]) for r in rows if r["orbit_step"] == "full"]
    half = [float(r["ratio"]) for r in rows if r["orbit_step"] == "half"]
    return f"{min(full):.2f}–{max(full):.2f}× the paper's, instead of {min(half):.1f}–{max(half):.1f}×"


@quote("tdheps_second")
def _tdheps_second(R):
    c = next(c for c in R.claims("tdheps_variants") if c["claim"].startswith("A second TDHeps"))
    return "to " + c["ours"].split("difference ")[1].split(" ")[0]


@quote("tdheps_r2")
def _tdheps_r2(R):
    rows = {r["corrector"]: r for r in _variants(R) if r["orbit"] == "R2"}
    unit, ours = rows["unit mass (eq. 36)"], rows["M^-1"]
    return (f"X1 = {sci(float(unit['X1']), 3)} at t = {power(float(unit['t_end']))}: the "
            f"paper's Fig. 9 value, {sci(float(unit['paper']))}. varint keeps M⁻¹ "
            f"(δqᵀ D²V M⁻¹ D²V δq) and its level there is {sci(float(ours['X1']))}")


@quote("stability_range")
def _stability_range(R):
    rows = {r["scheme"]: float(r["tau_max"]) for r in R.csv("stress_stability")}
    lo, hi = min(rows, key=rows.get), max(rows, key=rows.get)
    return (f"{rows[lo]:.2g} ({lo}) to {rows[hi]:.2g} ({hi}), {rows['ABA864']:.2g} for ABA864 "
            f"and {rows['SBAB2C']:.3g} for SBAB2C")


@quote("compensated_floor")
def _compensated_floor(R):
    floors = {(f["orbit"], f["t_end"], f["compensated"]): f["floor"]
              for f in R.json("compensated_floor")["floors"]}
    return ", ".join(f"{sci(floors['R1', t, False])} to {sci(floors['R1', t, True])} at t = "
                     f"{power(t)}" for t in (1e3, 1e4))


@quote("processed_frontier")
def _processed_frontier(R):
    res = R.json("frontier")
    ratios = {(r["orbit"], r["target"]): r for r in res["ratios"]}
    floors = {(f["orbit"], f["contender"]): f["floor"] for f in res["floors"]}

    def x(v, scheme=None):
        return ("does not reach it" if v is None else
                f"runs at {v:.2f}× heyoka's speed" + (f" ({scheme})" if scheme else ""))

    parts = [f"at a global error of {power(t)} the best processed scheme "
             f"{x(ratios['R1', t]['cpu_ratio_processed'], ratios['R1', t]['cpu_processed_scheme'])}"
             f", the best plain one {x(ratios['R1', t]['cpu_ratio_plain'])}"
             for t in (1e-10, 1e-12)]
    return ("; ".join(parts) + f"; the processed schemes' floor is "
            f"{sci(floors['R1', 'processed'])}, the plain ones' {sci(floors['R1', 'plain'])} "
            f"(R1, t = {power(res['t_end'])}, CPU time, load {res['load']['before'][0]:.1f} on "
            f"{res['load']['cpus']} CPUs)")


@quote("compensated_cost")
def _compensated_cost(R):
    res = R.json("compensated_floor")
    one, batch = res["one_orbit_cost"], res["batch_cost"]
    load = res["load"]["before"][0]
    return (f"{one['median']:.2f}× the CPU time of plain summation for one orbit (median of "
            f"{one['pairs']} steps and schemes; {one['min']:.2f}–{one['max']:.2f}×) and "
            f"{batch['ratio_cpu']:.1f}× for {batch['orbits']} orbits, which then run one at a "
            f"time instead of as SIMD lanes (load {load:.1f} on {res['load']['cpus']} CPUs)")


@quote("tm_spectrum_ns")
def _tm_spectrum_ns(R):
    r = next(r for r in R.json("bench_stepper")["rows"]
             if r["case"] == "R1 spectrum SBAB2C, QR every step")
    return f"{r['varint']:.0f} ns"


@quote("orbit_only")
def _orbit_only(R):
    ob = R.json("bench_peers")["orbit"]
    v = next(r for r in ob["rows"] if r["peer"] == "varint")
    eq = ob["heyoka_at_varint_error"]
    return f"{eq['ns_per_tau']:.0f} against {v['ns_per_tau']:.0f} ns per τ"


# -- the paper, re-measured ------------------------------------------------------------

@quote("paper_summary")
def _paper_summary(R):
    from studies import report

    t1 = R.json("table1")
    rows = t1["rows"]
    by = {(r["method"], r["tau"], r.get("delta")): r for r in rows}
    tm, dop = by["TM", 0.05, None], by["DOP853", 0.05, 1e-05]
    cc, eps = by["TDHcc", 0.05, None], by["TDHeps", 0.05, None]
    dops = [r for r in rows if r["method"] == "DOP853"]
    basis = [r for r in dops if r.get("cpu_basis", "extrapolated" if r["resumed"] else
                                      "measured") != "measured"]
    folder = R.folder
    cells = report.table1_verdicts(folder)
    claims = report.load_claims(folder)
    paper = [i for name, items in claims.items() for i in items
             if report.source(name, i) == "paper"]
    n, hold, _, differ, none = report._counts(paper)
    cost = next(c for c in R.claims("table1") if c["claim"].startswith("DOP853 needs"))
    return (f"Table I to t = {power(t1['horizon'])}, on one core of this machine, all "
            f"{len(rows)} rows measured: the TM row at τ = 0.05 (full spectrum, QR every step) "
            f"took {tm['cpu_s']:.0f} s of CPU (the paper: {tm['cpu_paper']}) and gives "
            f"X1 = {sci(tm['X1'], 3)} ({sci(tm['X1_paper'])}), energy error "
            f"{sci(tm['energy_error'])} ({sci(tm['energy_error_paper'])}). TDHcc and TDHes give "
            f"X1 = {sci(cc['X1'])} ({sci(cc['X1_paper'])}); TDHeps {sci(eps['X1'])} "
            f"({sci(eps['X1_paper'])}: see above). DOP853 runs on a compiled engine, bit for "
            f"bit SciPy's method, and gives X1 = {sci(dop['X1'], 3)} ({sci(dop['X1_paper'])}) at "
            f"τ = 0.05; it costs {cost['ours'].split(';')[0]} against the paper's "
            f"{dop['cpu_ratio_paper']:.1f}× (the table's note says why). The "
            f"{len(dops)} DOP853 rows took {sum(r['cpu_s'] for r in dops) / 3600:.1f} CPU hours"
            + (f" ({len(basis)} of them extrapolated from a resumed run's last session, said "
               "so in their rows)" if basis else "")
            + f". Of Table I's {cells[0]} cells (X1 and energy error per row) {cells[1]} agree "
            f"with the paper's and {cells[2]} differ, each with its explanation or the word "
            f"*unexplained*. Of the {n} claims of the paper's text and figures (with those "
            f"about the two-particle method it left out), {hold} hold, {differ} differ and "
            f"{none} cannot be compared at our horizons")


# -- lattices ------------------------------------------------------------------------

_LATTICE_CASES = (("ddnls", "DDNLS 1D"), ("ddnls2d", "DDNLS 2D"), ("fput", "FPUT"),
                  ("kg", "KG"))


@quote("lattice_ranking")
def _lattice_ranking(R):
    rank = R.json("lattices_efficiency")["ranking"]
    lines = ["", "| case, target error | fastest, then (time relative to it) |", "|---|---|"]
    for case, label in _LATTICE_CASES:
        for target in sorted({r["target"] for r in rank if r["case"] == case}, reverse=True):
            rows = sorted((r for r in rank if r["case"] == case and r["target"] == target),
                          key=lambda r: r["relative"])
            if rows:
                lines.append(f"| {label}, {power(target)} | {rows[0]['method']}, then "
                             + ", ".join(f"{r['method']} {r['relative']:.3g}" for r in rows[1:])
                             + " |")
    return "\n".join(lines) + "\n"


def _rank(R, case, target, method):
    return next(r for r in R.json("lattices_efficiency")["ranking"] if r["case"] == case
                and r["target"] == target and r["method"] == method)


@quote("lattice_kg_speed")
def _lattice_kg_speed(R):
    speed = R.json("lattices_efficiency")["speed"]
    kg = next(r for r in speed if "plain" in r["model"])
    kg2 = next(r for r in speed if "(100, 100)" in r["model"])
    run = R.json("lattices_kg2d")["kg2d"]
    return (f"A KG chain of {kg['sites']} sites costs {kg['ns_per_site_step']:.1f} ns per site "
            f"and step with one vector, {kg['ratio']:.2f}× a plain compiled loop of the same "
            f"step; a 100 × 100 KG lattice costs {1e3 * kg2['seconds_per_step']:.2f} ms per "
            f"step, and its run to t = {power(run['t_end'])} at τ = 0.05 took "
            f"{run['cpu_s'] / 60:.1f} min of CPU")


@quote("lattice_taylor")
def _lattice_taylor(R):
    rel = [r["relative"] for r in R.json("lattices_efficiency")["ranking"]
           if r["method"] == "Taylor (heyoka)"]
    return f"{ratio(min(rel))}–{ratio(max(rel))}×"


def _law(R, case):
    return next(r for r in R.json("lattices_laws")["laws"] if r["case"].startswith(case))


@quote("lattice_laws")
def _lattice_laws(R):
    kg, dd = _law(R, "KG 1D weak"), _law(R, "DDNLS 1D strong")
    dw, kg2 = _law(R, "DDNLS 1D weak"), _law(R, "KG 2D")

    def fit(r, what):
        return f"t^{r[what + '_exponent']:.2f} ± {r[what + '_stderr']:.2f}".replace("-", "−")

    return (f"1D weak-chaos KG to t = {power(kg['t_end'])} gives Λ ∝ {fit(kg, 'x1')} (paper "
            f"{kg['x1_paper']:g}) and m₂ ∝ {fit(kg, 'm2')} (1/3); 1D strong-chaos DDNLS to "
            f"{power(dd['t_end'])} gives Λ ∝ {fit(dd, 'x1')} ({dd['x1_paper']:g}) and m₂ ∝ "
            f"{fit(dd, 'm2')} (1/2); the weak-chaos DDNLS (Λ ∝ t^{dw['x1_exponent']:.2f}, m₂ ∝ "
            f"t^{dw['m2_exponent']:.2f}) and the 2D KG packet (Λ ∝ t^{kg2['x1_exponent']:.2f}, "
            f"m₂ ∝ t^{kg2['m2_exponent']:.2f} against 1/5) are still in their transients at "
            f"{power(min(dw['t_end'], kg2['t_end']))}").replace("-0.", "−0.").replace("−−", "−")


# -- the How-fast table --------------------------------------------------------------

@quote("how_fast")
def how_fast(R):
    """README's "How fast" table, every cell from a stored result."""
    rows = []
    st = R.json("bench_stepper")
    by = {r["case"]: r for r in st["rows"]}
    where = measured_in(st, "bench_stepper")
    for case, label, against in (
            ("HH orbit only, ABA864", "Hénon–Heiles orbit only, ABA864",
             "C loop of the same 15 stages (gcc -O3)"),
            ("R1 spectrum SBAB2C, QR every step", "R1 spectrum, SBAB2C, QR every step",
             "C loop of the same algorithm"),
            ("R1 spectrum SBAB2C, sparse renormalisation",
             "R1 spectrum, SBAB2C, adaptive renormalisation", "the same C loop")):
        r = by.get(case)
        if r:
            rows.append((label, f"{r['varint']:.1f} ns/step (CPU)",
                         f"{against}, {r['reference']:.1f} ns", _ratio_cell(r["ratio"], r["spread"]),
                         where))
    r = by["1000 outputs / 2 outputs"]
    rows.append((f"1000 outputs over {st['n_steps'] // 10:.0e} steps (adaptive renormalisation)"
                 .replace("e+0", "e"), f"{1e3 * r['varint']:.1f} ms", "2 outputs",
                 _ratio_cell(r["ratio"], r["spread"]), where))
    r = by["first run in a new process (s)"]
    rows.append(("first run in a new process (R1 spectrum to t = 100, kernels cached)",
                 f"{r['varint']:.2f} s (CPU)", "—", "—", where))

    peers = R.json("bench_peers")
    sp = peers["spectra"]
    where = _peers_measured(R, "spectra")
    r1 = sp["R1"]
    for pick, label in ((lambda e: e["varint"].startswith("defaults"), "defaults"),
                        (lambda e: e["varint"] == "SRKN14a τ=1", "SRKN14a τ = 1")):
        e = next((e for e in r1["equal_error"] if pick(e) and e["heyoka"] == "QR every 100"),
                 None)
        if e:
            rows.append((f"R1 spectrum to {r1['t_end']:.0e}, {label}"
                         .replace("e+0", "e") + f", X1 error {sci(e['X1_error'])}",
                         f"{e['varint_s']:.3f} s", f"heyoka at that error, QR every 100: "
                         f"{e['heyoka_s']:.2f} s", _ratio_cell(e["heyoka_over_varint"],
                                                               e.get("spread"), faster=True),
                         where))
    c1 = sp["C1"]
    eq = c1["equal_error"]
    if eq and "reference_sample" in c1:
        v = eq[0]
        rows.append((f"C1 spectrum to {c1['t_end']:.0e}".replace("e+0", "e")
                     + f", X1 of {c1['reference_sample']['n']} nearby orbits distributed as "
                     "the reference's (KS p ≥ 0.01), " + v["varint"],
                     f"{1e3 * v['varint_s']:.1f} ms",
                     "cheapest such heyoka, " + " / ".join(e["heyoka"] for e in eq) + ": "
                     + " / ".join(f"{1e3 * e['heyoka_s']:.0f}" for e in eq) + " ms",
                     " / ".join(_ratio_cell(e["heyoka_over_varint"], e.get("spread"))
                                for e in eq) + " faster", where))
    maps = peers["maps"]
    where = _peers_measured(R, "maps")
    for e in maps["equal_quality"]:
        v = next(r for r in maps["rows"] if r["peer"] == "varint"
                 and r["indicator"] == e["indicator"] and r["config"] == e["varint"])
        fixed = f"heyoka batch 8, tol 1e-6: {ratio(e['varint_over_hy_b8_1e6'])}×"
        same = ("" if e["heyoka_equal"] is None else
                f"; the fastest heyoka as good ({e['heyoka_equal']}): "
                f"{ratio(e['varint_over_heyoka_equal'])}×")
        hy = next(r for r in maps["rows"] if r["indicator"] == e["indicator"]
                  and r["config"] == "hand, batch 8, tol 1e-06")
        rows.append((f"{e['indicator'].upper()} map, {maps['orbits']} orbits of the x = 0 "
                     f"section, t = {power(maps['t_end'])}, 1 thread"
                     + (" (CPU time)" if maps.get("clock") == "cpu" else "")
                     + f", {e['varint']}".replace("e+0", "e"),
                     f"{thousands(v['orbits_per_s'])} orbits/s, {100 * v['agreement']:.2f} % "
                     "agreement", fixed + same,
                     _ratio_cell(e["varint_over_hy_b8_1e6"], _turn_spread(hy, v),
                                 faster=True), where))
    two = [r for r in maps["rows"] if r["peer"] == "varint" and r["config"].startswith(
        "defaults") and r.get("orbits_per_s_2_threads")]
    if two:
        rows.append(("FLI / SALI / MEGNO map on 2 threads", " / ".join(
            thousands(r["orbits_per_s_2_threads"]) for r in two) + " per s", "1 thread",
            " / ".join(ratio(r["orbits_per_s_2_threads"] / r["orbits_per_s"]) for r in two)
            + " (one run)", where))
    else:
        th = R.json("threads")
        by = {r["indicator"]: r for r in th["rows"]}
        inds = [i for i in ("fli", "sali", "megno") if i in by]
        chose = " / ".join("2" if by[i]["default_parallel"] else "1" for i in inds)
        rows.append((f"{' / '.join(i.upper() for i in inds)} map, {by[inds[0]]['orbits']} "
                     f"orbits, t = {power(by[inds[0]]['t_end'])}, on 2 threads by default "
                     f"(it ran on {chose}; `parallel=True` forced: "
                     + " / ".join(ratio(by[i]["forced_over_1"]) for i in inds) + "×)",
                     "—", "1 thread",
                     " / ".join(ratio(by[i]["default_over_1"]) for i in inds) + " (one run)",
                     measured_in(th, "threads")))
    rows += _frontier_rows(R) + _singular_map_rows(R)
    # The smallest size of issue 28's target (n = 64 … 4096) and the largest.
    for fpu in (r for r in peers["fpu"]["rows"] if r["n"] in (64, 4096)):
        rows.append((f"FPU-β n = {fpu['n']}, one vector, ABA864",
                     f"{fpu['varint_ns_per_step'] / 1e3:.2f} µs/step (CPU)",
                     f"plain numba loop of the same step, "
                     f"{fpu['numba_ns_per_step'] / 1e3:.2f} µs",
                     _ratio_cell(fpu["varint_over_numba"], None), _peers_measured(R, "fpu")))
    if "lattice" in peers:
        lt = peers["lattice"]
        for e in lt["equal_energy_error"]:
            bound = "at most " if e["how"] == "at most" else ""
            rows.append((f"KG chain N = {lt['n']}, one vector, to t = {lt['t_end']:g}, varint "
                         f"{e['varint']} (with its pilot)",
                         f"{e['varint_s']:.2f} s, energy error {e['energy_error']:.0e}",
                         f"heyoka's Taylor method at that error, {bound}{e['heyoka_s']:.2f} s",
                         "—" if e["heyoka_over_varint"] is None else
                         f"{bound}{_ratio_cell(e['heyoka_over_varint'], None, faster=True)}",
                         _peers_measured(R, "lattice")))

    lat = R.json("lattices_efficiency")
    where = measured_in(lat, "lattices")
    kg = next(r for r in lat["speed"] if "plain" in r["model"])
    rows.append((f"KG chain, N = {kg['sites']}, one vector",
                 f"{kg['ns_per_site_step']:.1f} ns/site/step",
                 f"plain numba loop of the same step, {kg['plain_ns_per_site_step']:.1f}",
                 _ratio_cell(kg["ratio"], None), where))
    taylor = [r["relative"] for r in lat["ranking"] if r["method"] == "Taylor (heyoka)"]
    rows.append(("FPUT and KG chains, 256 sites, at equal energy error", "—", "heyoka Taylor",
                 f"{ratio(min(taylor))}–{ratio(max(taylor))}× faster (over targets)", where))
    kg2d = R.json("lattices_kg2d")["kg2d"]
    side = kg2d["model"].split("shape=(")[1].split(")")[0].replace(", ", " × ")
    rows.append((f"KG 2D, {side}, one vector, ABA864 τ = 0.05, to t = "
                 f"{power(kg2d['t_end'])}",
                 f"{kg2d['cpu_s'] / 60:.1f} min of CPU (one run)", "the target, 10 min", "—",
                 measured_in(R.json("lattices_kg2d"), "lattices --part kg2d")))

    lib = R.json("bench_libraries")
    where = measured_in(lib, "bench_libraries")
    for library, ours, against in (
            ("scikit-sundae", "CVODE baseline (`method=\"cvode\"`), at equal orbit error",
             "scikit-sundae's CVODE driven directly (one solve, its defaults)"),
            ("heyoka", "Taylor baseline (`method=\"taylor\"`), same tolerance",
             "heyoka driven directly (one `propagate_grid`)"),
            ("SciPy", "DOP853 engine, δ = 1e-5 restarted every τ",
             "SciPy's DOP853 driven directly, δ = 1e-5 … 1e-13, and restarted every τ")):
        mine = [c for c in lib["claims"] if f"as accurate as {library} " in c["claim"]]
        values = [j["value"] for c in mine for j in c["rules"] if j["value"] is not None]
        held = sum(c["holds"] for c in mine)
        rows.append((f"{ours}; R1 and C1, k = 1 and 4, QR every τ", "—", against,
                     f"{ratio(min(values))}–{ratio(max(values))}× faster (holds its own in "
                     f"{held} of {len(mine)} cases; ≥ 1/1.1 is as fast within the noise)",
                     where))
    bb = R.json("bench_baselines")
    d = {(r["config"], r["k"]): r for r in bb["methods"]}
    fast, slow = d["dop853 delta=1e-5", 4], d["dop853 delta=1e-5, SciPy's solver", 4]
    rows.append(("R1 spectrum, DOP853 δ = 1e-5 restarted every τ, compiled engine (SciPy's "
                 "method, bit for bit)", f"{fast['ms_per_tu']:.3f} ms/tu",
                 f"SciPy's solver: {slow['ms_per_tu']:.2f} ms/tu ({slow['time']})",
                 f"{ratio(slow['ms_per_tu'] / fast['ms_per_tu'])}× faster (one run)",
                 measured_in(bb, "bench_baselines")))
    head = "| case | varint | against | ratio (spread over repeats) | measured by |\n"
    head += "|---|---|---|---|---|\n"
    return "\n" + head + "".join("| " + " | ".join(r) + " |\n" for r in rows)


def _short(rule):
    """A judgement's value in a table cell."""
    return (f"{rule['value']:.2f}×" if rule["value"] is not None else "—")


#: The role of a quote in reStructuredText.
ROLE = re.compile(r":q:`([^`]+)`")


def rst_prose(text):
    """The prose of a reStructuredText page: quotes (``:q:`NAME```),
    inline literals, literal and code blocks and doctest examples with
    their output blanked, line numbers kept."""
    text = ROLE.sub(lambda m: " " * len(m[0]), text)
    text = re.sub(r"``.*?``", lambda m: re.sub(r"[^\n]", " ", m[0]), text, flags=re.S)
    lines, out, literal, doctest = text.splitlines(), [], False, False
    for line in lines:
        stripped = line.strip()
        if literal and stripped and not line[:1].isspace():
            literal = False
        if doctest and not stripped:
            doctest = False
        if stripped.startswith((">>>", "...")):
            doctest = True
        out.append("" if literal or doctest else line)
        if stripped.endswith("::") or stripped.startswith(".. code-block::"):
            literal = True
    return "\n".join(out)


#: Pages the documentation's build writes (not committed).
_BUILT = {"sg_execution_times.rst"}


def docs_pages():
    """The documentation's reStructuredText pages (the site's prose)."""
    docs = ROOT / "docs"
    return sorted(p for pattern in ("*.rst", "user_guide/*.rst") for p in docs.glob(pattern)
                  if p.name not in _BUILT)


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="only report stale quotes and unsourced numbers")
    args = parser.parse_args(argv)
    text = README.read_text()
    results = Results()
    if not args.check:
        new = fill(text, results)
        if new != text:
            README.write_text(new)
            print(f"README.md: {len(stale(text, results))} quote(s) rewritten")
        text = new
    for name, written, now in stale(text, results):
        print(f"stale: {name}: {written!r} -> {now!r}")
    for line, content in unsourced(text):
        print(f"unsourced: README.md:{line}: {content}")
    for page in docs_pages():
        rst = page.read_text()
        for m in ROLE.finditer(rst):
            try:
                render(m[1], results)
            except (KeyError, LookupError, FileNotFoundError) as exc:
                print(f"no source: {page.relative_to(ROOT)}: {m[1]}: {exc}")
        for line, content in unsourced(rst_prose(rst)):
            print(f"unsourced: {page.relative_to(ROOT)}:{line}: {content}")


# -- the test suite ------------------------------------------------------------

@quote("planetary_race")
def _planetary_race(R):
    """The MEGNO map race with REBOUND in a process pool
    (``studies/race_planetary.py``): horizon, ratios and agreements."""
    d = R.json("race_planetary")
    rows = {row["code"]: row for row in d["rows"]}
    reb, var = rows["REBOUND"], rows["varint"]
    lo, hi = d["load_average"]
    # Older results count the horizon in orbits of the inner planet only.
    unit = d.get("periods_of", "inner")
    horizon = d["periods"] if "periods" in d else d["inner_periods"]
    where = " at the grid's middle" if unit == "outer" else ""
    return (f"{d['grid_points']} points over {horizon:g} orbits of the {unit} planet{where} "
            f"(t ≈ {sci(d['t_end'], 3)}), {d['workers']} REBOUND workers and {d['workers']} varint "
            f"threads, load average {lo:.0f} → {hi:.0f} on {d['cores']} shared cores: REBOUND took "
            f"{ratio(d['rebound_over_varint'])}× varint's CPU time with early stopping "
            f"({spread(reb['time_over_varint_per_block'])}× over the blocks) and "
            f"{ratio(d['rebound_over_varint_no_early_stopping'])}× without; on {d['sample']} "
            f"sample points varint's verdicts agree with heyoka at tolerance 1e-15 on "
            f"{var['agreement_with_reference']:.1%}, REBOUND's on "
            f"{reb['agreement_with_reference']:.1%}; varint's and REBOUND's verdicts agree on "
            f"{var['agreement_with_rebound']:.1%} of the grid")


@quote("planetary_profile")
def _planetary_profile(R):
    """Where a planetary map point's step goes (``studies/planetary_profile.py``)."""
    d = R.json("planetary_profile")
    ns, sh = d["ns_per_step"], d["share_of_map_step"]
    lo, hi = d["load_average"]
    return (f"{ns['map, MEGNO']:.0f} ns of CPU time (REBOUND's WHFast with MEGNO "
            f"{ns['REBOUND WHFast + MEGNO']:.0f} ns, {ratio(d['rebound_over_varint_per_step'])}×; "
            f"load {lo:.0f} → {hi:.0f}): the planets' Kepler equations {sh['kepler solve']:.0%}, "
            f"the f and g update {sh['f, g update of the orbit']:.0%}, the tangent map of the "
            f"drift {sh['tangent of the drift']:.0%}, the interaction kick "
            f"{sh['kick (orbit)']:.0%} and its tangent {sh['tangent of the kick']:.0%}, the end "
            f"of every interval {sh['end of interval and FLI']:.0%} and MEGNO's update "
            f"{sh['MEGNO beyond FLI']:.0%}")


@quote("planetary_lanes")
def _planetary_lanes(R):
    """Lanes against one orbit at a time (``studies/planetary_lanes.py``)."""
    d = R.json("planetary_lanes")
    lo, hi = d["load_average"]
    ns = d["ns_per_point_step"]
    return (f"a block of {d['points']} points steps {ratio(d['lanes_speedup'])}× as fast as one "
            f"orbit at a time ({ns['lanes']:.0f} against {ns['one orbit at a time']:.0f} CPU ns "
            f"per point and step of dt, one thread, load {lo:.0f} → {hi:.0f})")


@quote("planetary_map_lanes")
def _planetary_map_lanes(R):
    """A planetary MEGNO map in lanes against one orbit at a time
    (``studies/planetary_map_lanes.py``)."""
    d = R.json("planetary_map_lanes")
    lo, hi = d["load_average"]
    s = d["lanes_speedup"]
    return (f"on {d['grid_points']} points of the race's grid over {d['inner_periods']:g} orbits "
            f"of the inner planet, one thread, the map in lanes ran {ratio(s['early stopping'])}× "
            f"as fast as one orbit at a time (CPU time) with early stopping and "
            f"{ratio(s['no early stopping'])}× without, bit for bit alike (load {lo:.0f} → "
            f"{hi:.0f})")


@quote("planetary_lane_cache")
def _planetary_lane_cache(R):
    """The first planetary MEGNO map of a new process, its kernels' cache
    warm against cold, and before the lanes were cached
    (``studies/planetary_lane_cache.py``: medians of new processes, wall
    time)."""
    d = R.json("planetary_lane_cache")
    s = d["summary"]
    lo, hi = d["_provenance"]["machine"]["load"], d["_provenance"]["load_end"]
    return (f"{s['after warm']['median wall s']:.1f} s against "
            f"{s['after cold']['median wall s']:.0f} s cold, and "
            f"{s['before warm']['median wall s']:.0f} s when the lanes compiled in every "
            f"process (medians of {len(d['runs']['after warm'])} new processes, the same bits; "
            f"load {lo:.0f} → {hi:.0f} on 2 cores)")


@quote("startup_quiet")
def _startup_quiet(R):
    """The first run of a new process with warm caches on a quiet machine
    (``studies/startup.py --label quiet41m``: medians of fresh processes,
    wall time from before ``import varint`` to the end of the run)."""
    d = R.json("startup_quiet41m")
    t = {case: row["import_plus_first_run_median_s"] for case, row in d["this"].items()}
    announced = d["this"]["potential"]["announced"]
    lo, hi = d["load"]["before"][0], d["load"]["after"][0]
    return (f"{t['r1']:.2f} s for `import varint` and a first R1 spectrum, against "
            f"{t['floor']:.2f} s for NumPy, numba and one cached trivial kernel; "
            f"{t['lattice']:.2f} s for a first lattice run, {t['map2'] - t['map1']:.3f} s more "
            f"for a first map on 2 threads than on 1, and {t['potential']:.1f} s for a new "
            f"`from_potential` model (its compile announced in {announced} of "
            f"{d['processes']}); medians of {d['processes']} new processes, commit "
            f"{d['_provenance']['code']['commit'][:7]}, load {lo:.1f} → {hi:.1f} on 2 cores")


@quote("suite_time")
def _suite_time(R):
    """How long the default suite took, cold, as CI runs it
    (``studies/suite_time.py``): wall and CPU time, cores, load."""
    s = R.json("suite_time")["cold"]
    # pytest's closing line without its rule and time (older results kept both).
    summary = re.sub(r"^=+\s*|\s+in [\d.]+s.*$", "", s["summary"])
    return (f"{s['wall_s'] / 60:.0f} min cold ({s['cpu_s'] / 60:.0f} min of CPU) on "
            f"{s['cores']} cores at load {s['load_start'][0]:.1f}: {summary}")


@quote("prepared_cost")
def _prepared_cost(R):
    """A prepared one-step R1 call (its short path) against the one-shot
    call and the same prepared call by the general path
    (studies/call_profile.py, round5: minimum wall time of interleaved
    rounds)."""
    d = R.json("call_profile_round5")
    load = d["load"]["after"][0]
    return (f"{d['prepared']['whole_call']['wall_min_us']:.0f} µs, "
            f"{d['prepared_over_oneshot']['wall_min']:.2f} of the one-shot call's time "
            f"({d['whole_call']['wall_min_us']:.0f} µs) and "
            f"{d['prepared_over_prepared_general']['wall_min']:.2f} of the same call by the "
            f"general path ({d['prepared_general']['whole_call']['wall_min_us']:.0f} µs; "
            f"minimum of {d['calls']} calls, load {load:.0f} on {d['load']['cpus']} cores)")


@quote("remembered_cost")
def _remembered_cost(R):
    """A one-step R1 call repeating a remembered call's arguments, against
    the same call on the baseline tree (``call_overhead.py --baseline``, a
    tree without remembered calls, which builds it anew) and the prepared
    call (minimum CPU time over interleaved rounds; whether every case's
    results were bitwise equal, as stored)."""
    d = R.json("call_overhead")
    s = d["summary"]
    lo, hi = d["_provenance"]["machine"]["load"], d["_provenance"]["load_end"]
    same = all(s[case]["bitwise_equal"] for case in ("fixed", "frontier", "prepared"))
    return (f"{s['fixed']['this_cpu_us']:.0f} µs of CPU against "
            f"{s['fixed']['baseline_cpu_us']:.0f} µs built anew "
            f"({s['fixed']['ratio_cpu']:.1f}×; the prepared call "
            f"{s['prepared']['this_cpu_us']:.0f} µs; minimum of {d['rounds']} rounds of "
            f"{d['calls']} calls, {'bitwise equal' if same else 'NOT bitwise equal'}, "
            f"load {lo:.1f} → {hi:.1f})")


@quote("lh_defaults")
def _lh_defaults(R):
    """studies/lh_defaults.py: per FLI map, the spread of U over its
    initial conditions, what the defaults ran, and their time, and the LH
    map's at its step chosen by indicator agreement, over the constant-step
    map's (energy pilot), pilots included; the seconds per force
    evaluation of the LH run over the constant-step run's."""
    d = R.json("lh_defaults_quick")
    parts = []
    for r in d["rows"]:
        dflt = r["defaults"]
        ran = ("the logarithmic Hamiltonian" if dflt["method"] == "tm+log"
               else f"constant steps (step by {dflt['rule']})")
        parts.append(f"{r['map']} (U spreads {r['u_spread']:.2f}×): the defaults ran {ran} in "
                     f"{ratio(r['defaults_over_constant_seconds'])}× the time of the "
                     f"energy-tolerance constant steps, the LH map "
                     f"{ratio(r['log_over_constant_seconds'])}× "
                     f"({dflt['agreement_with_constant']:.0%} and "
                     f"{r['log']['agreement_with_constant']:.0%} of the orbits classified "
                     f"alike); a force evaluation of the LH "
                     f"{r['cost_ratio']:.2g}× one of constant steps")
    rows = d["rows"]
    load = max(d["load"][0], d["load_end"][0])
    return ("; ".join(parts) + f" ({min(r['orbits'] for r in rows)}–"
            f"{max(r['orbits'] for r in rows)} orbits to t = {rows[0]['t_end']:g}, "
            f"one thread, machine load up to {load:.0f} on 2 cores)")


@quote("lh_auto_h")
def _lh_auto_h(R):
    """studies/lh_defaults.py: each LH map's automatic h (indicator
    agreement) and the largest relative energy error over all its orbits
    and outputs."""
    d = R.json("lh_defaults_quick")
    parts = [f"{r['map']} h = {r['log']['step']:.3g}, largest error "
             f"{r['log']['max_energy_error']:.2g}" for r in d["rows"]]
    return "; ".join(parts) + " (the ceiling at the pilot's 90 % quantile: energy_tol = 1e-3)"


@quote("lh_yardstick_rules")
def _lh_yardstick_rules(R):
    """studies/lh_yardstick.py (first part): per map and step rule, the h
    chosen on the pilot and the held-out orbits' agreement with h/16."""
    d = R.json("lh_yardstick")
    parts = [f"{r['map']} {r['rule']}: h = {r['h']:.2g}, {r['agreement']:.0%} of "
             f"{r['held_out']}" for r in d["rows"]]
    load = max(d["load"][0], d["load_end"][0])
    return "; ".join(parts) + f" (machine load up to {load:.0f})"


@quote("lh_yardstick_ceilings")
def _lh_yardstick_ceilings(R):
    """studies/lh_yardstick.py --part ceilings: per map and energy ceiling
    of the verdict rule, the h chosen and the held-out orbits' agreement
    with h/16 (the reference's antimode) and their largest energy error."""
    d = R.json("lh_yardstick_ceilings")
    parts = [f"{r['map']}, ceiling {r['ceiling']:g}: h = {r['h']:.2g}, "
             f"{r['agreement']:.1%} of {r['held_out']}, energy error up to "
             f"{r['held_out_energy_error']:.2g}" for r in d["rows"]]
    load = max(d["load"][0], d["load_end"][0])
    return "; ".join(parts) + f" (machine load up to {load:.0f})"


@quote("lh_yardstick_retry")
def _lh_yardstick_retry(R):
    """studies/lh_yardstick.py --part retry: per map, the pilot's h at the
    ceiling 10 × energy_tol with every orbit retried to energy_tol, the
    held-out agreement with h/16, the share retried, and the force
    evaluations against one h at the ceiling energy_tol."""
    d = R.json("lh_yardstick_retry")
    rows = {(r["map"], r["ceiling"], r["retry"]): r for r in d["rows"]}
    parts = []
    for (name, ceiling, retry), r in rows.items():
        if not retry or ceiling != 0.01:
            continue
        one = rows[name, 0.001, False]
        parts.append(f"{name}: h = {r['h']:.2g}, {r['agreement']:.1%} of {r['held_out']}, "
                     f"{r['retried']:.0%} retried, energy error up to "
                     f"{r['held_out_energy_error']:.2g}, "
                     f"{r['gradients_per_orbit'] / one['gradients_per_orbit']:.2f}× the force "
                     f"evaluations of one h")
    load = max(d["load"][0], d["load_end"][0])
    return "; ".join(parts) + f" (machine load up to {load:.1f})"


@quote("lh_auto_race")
def _lh_auto_race(R):
    """studies/map_steps.py part log (quick maps): the LH map at its
    automatic h and the defaults against heyoka batch 8 at equal
    agreement, per map measured."""
    d = R.json("map_steps_quick_log")["log"]
    rows = {(r["map"], r["contender"]): r for r in d["rows"]}
    parts = []
    for name, s in d["summary"].items():
        auto, dflt = s["varint LH, automatic h"], s["varint defaults"]
        r = rows[name, "varint LH, automatic h"]
        parts.append(f"{name} ({r['orbits']} orbits to t = {r['t_end']:g}): the LH at its "
                     f"automatic h (h = {r['tau']:.3g}, "
                     f"{thousands(round(r['steps_per_orbit']))} steps per orbit) "
                     f"{ratio(auto['ratio'])}× heyoka at {auto['varint_agreement']:.0%} "
                     f"agreement, the defaults {ratio(dflt['ratio'])}×")
    load = max(d["load"][0], d["load_end"][0])
    return "; ".join(parts) + f" (one thread, machine load up to {load:.0f} on 2 cores)"


@quote("lh_race")
def _lh_race(R):
    """The logarithmic-Hamiltonian step on the chaos maps of
    studies/map_steps.py (part log, quick maps): steps per orbit, agreement
    and heyoka batch 8's time over varint's at the cheapest tolerance that
    reaches the same agreement."""
    d = R.json("map_steps_quick_log")["log"]
    rows = {(r["map"], r["contender"]): r for r in d["rows"]}
    summary = d["summary"]

    def one(name, contender):
        r, s = rows[name, contender], summary[name][contender]
        return (f"{thousands(round(r['steps_per_orbit']))} steps per orbit, "
                f"{s['varint_agreement']:.1%} of the orbits classified as the reference does, "
                f"{ratio(s['ratio'])}× heyoka")

    cr3, core = "varint LH ABA864, h 1.6, offset None", "varint LH ABA864, h 0.05, offset 0.25"
    half = "varint LH ABA864, h 0.8, offset None"
    fine = "varint LH ABA864, h 0.025, offset 0.25"
    load = max(d["load"][0], d["load_end"][0])
    three = rows["cr3bp", cr3]
    return (f"on the restricted three-body map (Sun–Jupiter, {three['orbits']} orbits to "
            f"t = {three['t_end']:g}, {100 * three['reference_chaotic']:.0f} % of them chaotic in the "
            f"reference) ABA864 with h = 1.6: {one('cr3bp', cr3)}, its FLI off the "
            f"reference's by a median {three['dfli_median']:.0f} on the regular orbits "
            f"(h = 0.8: {one('cr3bp', half)}; the defaults: "
            f"{one('cr3bp', 'varint defaults')}); on the cored "
            f"logarithmic potential ({rows['core', core]['orbits']} orbits about its centre to "
            f"t = {rows['core', core]['t_end']:g}, "
            f"{100 * rows['core', core]['reference_chaotic']:.0f} % of them chaotic in the "
            f"reference) ABA864 with h = 0.05 "
            f"and δ = 0.25: {one('core', core)} (h = 0.025: {one('core', fine)}; the defaults: "
            f"{one('core', 'varint defaults')}); one thread, machine load up to {load:.0f} on "
            f"2 cores")


@quote("numba_opt")
def _numba_opt(R):
    """CPU seconds of a cold test file at LLVM levels 0 and 1 over level 3
    (studies/numba_opt.py)."""
    d = R.json("numba_opt")
    best = d["best"]
    loads = [r["load"][0] for r in d["runs"]]
    return (f"on {', '.join(d['files'])} -O0 took {best['0']['cpu_ratio_to_O3']:.3f} times "
            f"the CPU seconds of -O3 and left {best['0']['uncacheable']} kernels numba cannot "
            f"cache, -O1 {best['1']['cpu_ratio_to_O3']:.3f} times (one cold run per level, load "
            f"{min(loads):.0f}–{max(loads):.0f} on 2 cores)")


if __name__ == "__main__":
    main()

