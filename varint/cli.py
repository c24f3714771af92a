"""The ``varint`` command line: the common jobs without writing Python.

    varint schemes                          the splitting schemes, order, cost
    varint run lyapunov --orbit R1          an indicator for a paper orbit or
    varint run sali --potential "..."       a model given as a potential
    varint run x1 --map standard --K 10     a symplectic map (iterations)
    varint run sali --potential "-cos(q)*(1+0.2*cos(1.5*t))" --coords q --time t
                                            a periodically driven system
    varint run fli --hamiltonian "..." --coords x,y --momenta px,py
                                            any H(q, p): rotating frames,
                                            magnetic fields, general H
    varint map --energy 0.125 ...           a chaos map of a surface of section
    varint map --map standard --K 1.2 ...   a chaos map of a map's phase space
    varint select --orbit R1 --target 1e-8  the cheapest scheme and step
    varint lattice dvd --model ddnls ...    a disordered lattice, one or many
                                            realisations
    varint study stress --quick             a study of studies/ (source checkout)
    varint demo                             R1 and C1, as ``python -m varint``

Results are printed as a table; ``--csv`` and ``--png`` write them to files
(every CSV also records the method, scheme, tau and seed that ran). The
command keeps no lists of its own: models, indicators, methods and schemes
come from their registries (:mod:`varint.models.registry`,
:data:`varint.INDICATORS`, :data:`varint.METHODS`, :data:`varint.SCHEMES`).
Bad arguments and failed runs end with a one-line error (exit status 2 for
arguments, 1 for a failed run or an internal error, 130 after Ctrl-C);
``varint --traceback COMMAND ...`` also prints the traceback.
"""

from __future__ import annotations

import argparse
import csv
import importlib
import math
import os
import re
import sys
import traceback
import warnings
from pathlib import Path

import numpy as np

from . import _validate as check
from .files import output_file

__all__ = ["main", "build_parser"]

#: Most steps (t_end / tau) one orbit of a command may take: 50 times the
#: paper's longest run (2e9 steps), about three hours at 100 ns a step.
MAX_STEPS = 10 ** 11
#: Most coordinates of --potential: its generated kernels grow as N² to N³
#: (a dense quartic in 32 coordinates takes 20 s to generate).
MAX_COORDS = 100


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (instead of usage + error), reading
    values that start with "-" as values."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # argparse takes "-1,0.1", "-0.4:0.6:50", "-1e-3" or "-x**2" for an
        # unknown option ("expected one argument") unless they match this.
        # The only single-dash option is -h, matched before this is asked.
        self._negative_number_matcher = re.compile(r"^-[^-]")

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


# -- option values ---------------------------------------------------------------
def _finite(text):
    """argparse type: a finite number."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {_shown(text)}")
    return value


def _positive(text):
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got "
                                         f"{_shown(text)}")
    return value


def _compensation(text):
    """argparse type: a partial level of the TM method's compensated
    summation (``--compensated`` alone is every drift and kick)."""
    if text in ("orbit", "step"):
        return text
    raise argparse.ArgumentTypeError(f"expected 'orbit' or 'step' (or no value: every drift "
                                     f"and kick compensated), got {_shown(text)}")


def _shown(text, limit=60):
    """``repr(text)``, shortened: values are quoted in one-line messages."""
    return repr(text if len(text) <= limit else text[:limit - 3] + "...")


def _integer(text, minimum, what):
    """``text`` as an integer >= ``minimum``, or ArgumentTypeError."""
    try:
        value = int(text)
    except ValueError:
        # "1e3" is a count too; "2.5" is not.
        try:
            number = float(text)
        except ValueError:
            number = math.nan
        value = int(number) if math.isfinite(number) and number.is_integer() else None
    if value is None or value < minimum:
        raise argparse.ArgumentTypeError(f"expected {what}, got {_shown(text)}")
    return value


def _count(text):
    """argparse type: an integer >= 1."""
    return _integer(text, 1, "a positive integer")


def _natural(text):
    """argparse type: an integer >= 0."""
    return _integer(text, 0, "an integer >= 0")


def _items(text, name):
    items = text.replace(",", " ").split()
    if not items:
        raise ValueError(f"{name} is empty; expected comma-separated numbers")
    return items


def _floats(text, name, count=None):
    """Comma-separated finite numbers (exactly ``count`` if given)."""
    values = []
    for item in _items(text, name):
        try:
            value = float(item)
        except ValueError:
            raise ValueError(f"{name} must be comma-separated numbers, got {_shown(item)} in "
                             f"{_shown(text)}") from None
        if not math.isfinite(value):
            raise ValueError(f"{name} must hold finite numbers, got {_shown(item)} in "
                             f"{_shown(text)}")
        values.append(value)
    if count is not None and len(values) != count:
        raise ValueError(f"{name} needs {count} numbers, got {len(values)} ({_shown(text)})")
    return values


def _ints(text, name, count, lo, hi):
    """Comma-separated integers in lo..hi (exactly ``count`` unless None)."""
    items = _items(text, name)
    expected = ("an integer" if count == 1 else "integers") + f" in {lo}..{hi}"
    values = []
    for item in items:
        try:
            values.append(_integer(item, lo, ""))
        except argparse.ArgumentTypeError:
            values.append(None)
        if values[-1] is None or values[-1] > hi:
            where = f" in {_shown(text)}" if len(items) > 1 else ""
            raise ValueError(f"{name} must be {expected}, got {_shown(item)}{where}")
    if count is not None and len(values) != count:
        raise ValueError(f"{name} needs {count} integers, got {len(values)} ({_shown(text)})")
    return values


def _grid_spec(text, name):
    """START:STOP:NUM as (start, stop, num), checked but not yet allocated."""
    parts = text.split(":")
    example = f"e.g. {name}=-0.45:0.7:200"
    if len(parts) != 3:
        raise ValueError(f"{name} must be START:STOP:NUM ({example}), got {text!r}")
    try:
        start, stop = (float(v) for v in parts[:2])
    except ValueError:
        raise ValueError(f"{name} must be START:STOP:NUM with numbers START and STOP "
                         f"({example}), got {text!r}") from None
    try:
        num = _count(parts[2])
    except argparse.ArgumentTypeError:
        raise ValueError(f"{name}: NUM must be a positive integer (the number of points), got "
                         f"{parts[2]!r} in {text!r}") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise ValueError(f"{name}: START and STOP must be finite, got {text!r}")
    if not stop > start:
        raise ValueError(f"{name} must be START:STOP:NUM with STOP > START, got {text!r}")
    if not math.isfinite(stop - start):
        raise ValueError(f"{name}: STOP - START must be finite (a double), got {text!r}")
    return start, stop, num


def _horizon(t_end, tau, t_name="--t-end", tau_name="--tau"):
    """(t_end, tau, steps) checked: positive, finite, at most MAX_STEPS steps
    (the command's limit checked first, so that its message names the
    options)."""
    def too_many(steps):
        return ValueError(f"{t_name} {t_end:g} / {tau_name} {tau:g} is {steps:.3g} steps, more "
                          f"than the {MAX_STEPS:.0e} a command runs; use a larger {tau_name} or "
                          f"a shorter {t_name}")

    tau = check.positive_float(tau, "tau")
    if isinstance(t_end, float) and math.isfinite(t_end) and t_end / tau > MAX_STEPS:
        raise too_many(t_end / tau)
    t_end, tau = check.horizon(t_end, tau)
    steps = t_end / tau
    if steps > MAX_STEPS:
        raise too_many(steps)
    return t_end, tau, max(1, round(steps))


# -- models and initial states -------------------------------------------------
def _registered(maps):
    """The registered models the command takes: flows, and maps with ``maps``."""
    from .models.registry import MODELS

    kinds = ("flow", "map") if maps else ("flow",)
    return [e for e in MODELS.values() if e.kind in kinds]


def _parameter_options(entries):
    """Each model parameter's option (``--beta``) → [(entry, parameter)]
    of the models that take it."""
    out = {}
    for entry in entries:
        for par in entry.parameters:
            out.setdefault(par.option, []).append((entry, par))
    return out


def _source(entry):
    """How a registered model is chosen on the command line."""
    return f"--{'map' if entry.kind == 'map' else 'model'} {entry.name}"


def _add_model_arguments(p, orbit=True, maps=False):
    from .models import PAPER_ORBITS

    entries = _registered(maps)
    group = p.add_argument_group("model (one of)")
    if orbit:
        group.add_argument("--orbit", help="a paper orbit, which fixes the model and the "
                           f"initial state: {', '.join(PAPER_ORBITS)}")
    flows = [e for e in entries if e.kind == "flow"]
    group.add_argument("--model", choices=[e.name for e in flows],
                       help="a built-in model: " + "; ".join(f"{e.name}: {e.summary}"
                                                             for e in flows))
    if maps:
        iterated = [e for e in entries if e.kind == "map"]
        group.add_argument("--map", choices=[e.name for e in iterated],
                           help="a symplectic map (t counts iterations): " + "; ".join(
                               f"{e.name}: {e.summary}, state {','.join(e.coordinates)}"
                               for e in iterated))
    group.add_argument("--potential", metavar="EXPR",
                       help="V(q) as a formula in the --coords, e.g. "
                       "'(x**2+y**2)/2 + x**2*y - y**3/3': numbers, + - * / ** ^, parentheses, "
                       "pi, E and sin, cos, tan, exp, log, sqrt, sinh, ..., atan2")
    group.add_argument("--hamiltonian", metavar="EXPR",
                       help="H(q, p) as a formula in the --coords and --momenta (same syntax as "
                       "--potential), e.g. '(px**2+py**2)/2 + y*px - x*py - 1/sqrt(x**2+y**2)': "
                       "its structure is recognised (varint.models.from_hamiltonian)")
    group.add_argument("--coords", metavar="NAMES",
                       help="the coordinates of --potential or --hamiltonian in order, e.g. x,y")
    group.add_argument("--momenta", metavar="NAMES",
                       help="the momenta of --hamiltonian in order, e.g. px,py")
    group.add_argument("--inverse-mass", metavar="M", help="diagonal of M^-1 for --potential "
                       "(default all 1)")
    if maps:
        group.add_argument("--time", metavar="NAME", help="the time variable of a "
                           "time-dependent --potential V(q, t) or --hamiltonian H(q, p, t), e.g. "
                           "t (integrated in the extended phase space from t = 0)")
    # One option per parameter of the registered models (varint.models.registry).
    for option, users in _parameter_options(entries).items():
        integer = all(par.integer for _, par in users)
        group.add_argument(option, type=_count if integer else _finite, help="; ".join(
            f"{_source(entry)}: {par.doc} (default {par.default:g})" for entry, par in users))


def _add_state_arguments(p):
    group = p.add_argument_group("initial state (with --model, --potential or --hamiltonian)")
    group.add_argument("--x0", metavar="Q,P", help="the full state q then p, comma-separated")
    group.add_argument("--energy", type=_finite, help="solve p[0] >= 0 from this energy, "
                       "with --q and --p giving the rest")
    group.add_argument("--q", metavar="Q", help="positions for --energy")
    group.add_argument("--p", metavar="P", help="momenta for --energy (p[0] is solved)")


def _given(args, *names):
    return [n for n in names if getattr(args, n, None) is not None]


def _refuse_unused(args, names, why):
    unused = _given(args, *names)
    if unused:
        raise ValueError(f"--{unused[0].replace('_', '-')} {why}")


def _model(args):
    """(model, x0 or None) from the model options: a paper orbit, a
    registered model with its parameters, or a potential."""
    from .models import paper_orbit
    from .models.registry import get_model

    sources = [a for a in ("orbit", "model", "potential", "hamiltonian", "map")
               if hasattr(args, a)]
    given = _given(args, *sources)
    if len(given) != 1:
        raise ValueError("give exactly one of " + ", ".join(f"--{a}" for a in sources)
                         + (f" (got {', '.join('--' + g for g in given)})" if given else ""))
    entry = get_model(getattr(args, given[0])) if given[0] in ("model", "map") else None
    values = {}
    for option, users in _parameter_options(_registered(hasattr(args, "map"))).items():
        value = getattr(args, option[2:].replace("-", "_"))
        if value is None:
            continue
        takes = [par for e, par in users if e is entry]
        if not takes:
            raise ValueError(f"{option} applies to "
                             f"{' and '.join(_source(e) for e, _ in users)} only")
        values[takes[0].name] = value
    if given[0] not in ("potential", "hamiltonian"):
        _refuse_unused(args, ("coords", "time"), "applies to --potential and --hamiltonian only")
    if given[0] != "potential":
        _refuse_unused(args, ("inverse_mass",), "applies to --potential only")
    if given[0] != "hamiltonian":
        _refuse_unused(args, ("momenta",), "applies to --hamiltonian only")
    if given[0] == "orbit":
        return paper_orbit(args.orbit)
    if entry is not None:
        return entry.build(**values), None
    if given[0] == "hamiltonian":
        return _hamiltonian_model(args), None
    return _potential_model(args), None


def _symbols(args, option):
    """The --coords of ``option`` (and --time), checked: (symbols, time)."""
    from .formula import coordinate_symbols

    if args.coords is None:
        raise ValueError(f"{option} needs --coords naming its coordinates, e.g. --coords x,y")
    names = [c.strip() for c in args.coords.split(",")]
    if len(names) > MAX_COORDS:
        raise ValueError(f"--coords names {len(names)} coordinates; at most {MAX_COORDS} (the "
                         "generated kernels grow as N^2 to N^3): write a Model with hand-written "
                         "kernels for larger systems, as varint.models.FPUBeta does")
    symbols = coordinate_symbols(names, "--coords")
    time = getattr(args, "time", None)
    if time is not None:
        time = coordinate_symbols([time.strip()], "--time")[0]
        if time.name in names:
            raise ValueError(f"--time {time.name} is also one of the --coords")
    return symbols, time


def _hamiltonian_model(args):
    from .formula import coordinate_symbols, parse_formula
    from .models import from_hamiltonian

    q, time = _symbols(args, "--hamiltonian")
    if args.momenta is None:
        raise ValueError("--hamiltonian needs --momenta naming the momenta of the --coords in "
                         "order, e.g. --momenta px,py")
    p = coordinate_symbols([m.strip() for m in args.momenta.split(",")], "--momenta")
    if len(p) != len(q):
        raise ValueError(f"--momenta names {len(p)} momenta for {len(q)} --coords")
    clash = sorted({s.name for s in p} & {s.name for s in q} | (
        {time.name} & {s.name for s in p} if time is not None else set()))
    if clash:
        raise ValueError(f"{clash[0]} is both a momentum and a coordinate (or the time)")
    variables = [s.name for s in (*q, *p)] + ([] if time is None else [time.name])
    H = parse_formula(args.hamiltonian, variables, "--hamiltonian")
    return from_hamiltonian(H, q, p, time=time, name=" ".join(args.hamiltonian.split()))


def _potential_model(args):
    from .formula import parse_formula
    from .models import from_potential

    symbols, time = _symbols(args, "--potential")
    names = [s.name for s in symbols]
    variables = names + ([] if time is None else [time.name])
    V = parse_formula(args.potential, variables, "--potential")
    minv = None
    if args.inverse_mass is not None:
        minv = _floats(args.inverse_mass, "--inverse-mass", len(names))
        bad = [m for m in minv if not m > 0]
        if bad:
            raise ValueError(f"--inverse-mass must be positive, got {bad[0]:g}")
    return from_potential(V, symbols, inverse_mass=minv, name=" ".join(args.potential.split()),
                          time=time)


def _state(args, model, x0):
    from .models import solve_momentum

    if x0 is not None:
        # A paper orbit is its initial state: any other would silently
        # replace it by something that is not the orbit the user named.
        _refuse_unused(args, ("x0", "energy", "q", "p"), f"does not apply to --orbit "
                       f"{getattr(args, 'orbit', '')}, which fixes the initial state; use "
                       "--model for another state")
    if args.x0 is not None and args.energy is not None:
        raise ValueError("give either --x0 or --energy (with --q/--p), not both")
    if _is_map(model) and args.energy is not None:
        raise ValueError(f"--energy: {model.name} is a map, which has no energy; give --x0 "
                         f"({','.join(model.variables)})")
    if args.energy is None:
        _refuse_unused(args, ("q", "p"), "goes with --energy (the energy fixes p[0])")
    if args.x0 is not None:
        return np.array(_floats(args.x0, "--x0", model.dim))
    if args.energy is not None:
        n = model.n_dof
        q = _floats(args.q, "--q", n) if args.q is not None else [0.0] * n
        p = _floats(args.p, "--p", n) if args.p is not None else [0.0] * n
        with np.errstate(over="ignore"):
            x = _solve_momentum(model, q, p, args.energy, solve_momentum)
        if not np.isfinite(x).all():
            raise ValueError(f"--energy {args.energy:g} gives a momentum p[0] = {x[n]:g} beyond "
                             "the range of a double")
        return x
    if x0 is None:
        raise ValueError("give the initial state: --x0, or --energy with --q/--p "
                         "(or use --orbit)")
    return x0


def _solve_momentum(model, q, p, energy, solve_momentum):
    """(q, p) with p[0] solved from the energy: ``solve_momentum`` for
    ½pᵀM⁻¹p + V(q), the model's own solver for any H(q, p) (on the branch
    q̇_0 ≥ 0)."""
    if not callable(getattr(model, "momentum_from_energy", None)):
        return solve_momentum(model, q, p, energy)
    x = np.concatenate([q, p]).astype(float)
    x[model.n_dof] = model.momentum_from_energy(x, energy, 0)
    if not np.isfinite(x[model.n_dof]):
        raise ValueError(f"no real momentum p[0] gives energy {energy!r} at q = {list(q)} "
                         "with the other momenta given (with q̇_0 >= 0)")
    return x


def _is_map(model):
    return getattr(model, "kind", "flow") == "map"


def _check_kernels(model, x, what="the initial state"):
    """Compile and evaluate the model's kernels at ``x`` before any long work:
    a potential numba cannot compile, or one singular at the start, is a bad
    argument, not a failed run."""
    from numba.core.errors import NumbaError

    if _is_map(model):
        values = (model.step(x), model.jacobian(x))
        if not all(np.isfinite(v).all() for v in values):
            raise ValueError(f"{model.name} or its tangent map is not finite at {what}, "
                             f"x = {_short(np.asarray(x, dtype=float))}")
        return
    q = np.ascontiguousarray(np.asarray(x, dtype=float)[:model.n_dof])
    try:
        if callable(getattr(model, "hessian_h", None)):
            # Any H(q, p): its gradient and Hessian in (q, p).
            state = np.ascontiguousarray(x, dtype=float)
            values = (model.gradient_h(state), model.hessian_h(state))
        else:
            values = (model.gradient(q), model.hessian_band(q),
                      model.third_band(q, np.ones_like(q)))
    except NumbaError as exc:
        reason = check.first_line(exc)
        if reason.startswith("Int value is too large"):
            reason += ("; an integer beyond 64 bits, e.g. from (2*x)**100: write its numbers "
                       "with a decimal point, (2.0*x)**100")
        raise ValueError(f"the kernels of {model.name} cannot be compiled: {reason}") from None
    except ArithmeticError as exc:
        raise ValueError(f"the derivatives of V ({model.name}) cannot be evaluated at "
                         f"{what}, q = {_short(q)}: {type(exc).__name__}: {exc}") from None
    if not all(np.isfinite(v).all() for v in values):
        raise ValueError(f"the derivatives of V ({model.name}) are not finite at {what}, "
                         f"q = {_short(q)}: V is singular, not real or too large there")


def _short(q, limit=8):
    """A coordinate vector for a one-line message (a long one elided)."""
    if len(q) <= limit:
        return str(q.tolist())
    return f"[{', '.join(f'{v:g}' for v in q[:3])}, ... ({len(q)} values)]"


def _check_run_size(model, k, n_out, what):
    """Refuse a run whose vectors and stored outputs would not fit in memory."""
    dim = model.dim
    # Deviation vectors and their QR workspace, the state, and per output
    # the state-sized and vector-sized records.
    needed = check.array_bytes((3, dim, k), (4, dim), (n_out, dim + k + 4))
    check.check_memory(needed, what)


# -- outputs ---------------------------------------------------------------------
def _check_outputs(args):
    """Every file a command writes, checked before its run starts."""
    paths = {}
    for attr, flag in (("csv", "--csv"), ("png", "--png")):
        value = getattr(args, attr, None)
        if value is None:
            continue
        path = check.output_file(value, flag)
        if attr == "png":
            _check_plot_format(path, flag)
        key = os.path.realpath(path)
        # Two outputs to one device (/dev/null) are fine; to one file, not.
        if key in paths and not (path.exists() and not path.is_file()):
            raise ValueError(f"{paths[key]} and {flag} name the same file {value}")
        paths[key] = flag


def _check_plot_format(path, flag):
    from matplotlib.backend_bases import FigureCanvasBase

    suffix = path.suffix[1:].lower()
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix and suffix not in formats:
        raise ValueError(f"{flag} {path}: matplotlib cannot write .{suffix} files; use one of "
                         f"{', '.join('.' + f for f in sorted(formats))}")


def _print_table(cols, rows=12):
    names = list(cols)
    n = len(cols[names[0]]) if names else 0
    pick = np.unique(np.round(np.linspace(0, n - 1, min(rows, n))).astype(int)) if n else []
    print("  ".join(f"{c:>12}" for c in names))
    for i in pick:
        print("  ".join(_cell(cols[c][i]) for c in names))
    if n > len(pick):
        print(f"({len(pick)} of {n} rows shown; --csv writes them all)")


def _cell(v):
    if isinstance(v, (int, np.integer)):
        return f"{int(v):>12d}"
    return f"{float(v):>12.5g}"


def _write_csv(path, cols, flag="--csv"):
    try:
        with output_file(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(list(cols))
            w.writerows(zip(*[np.asarray(c).tolist() for c in cols.values()], strict=True))
    except OSError as exc:
        raise OSError(f"cannot write {flag} {path}: {exc.strerror or exc}") from exc
    print(f"table written to {path}")


def _save_plot(result, path, **kwargs):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plotting import plot

    fig, ax = plt.subplots(figsize=(6, 4.5), layout="constrained")
    try:
        plot(result, ax, **kwargs)
        _savefig(fig, path)
    except OSError as exc:
        raise OSError(f"cannot write --png {path}: {exc.strerror or exc}") from exc
    finally:
        plt.close(fig)
    print(f"plot written to {path}")


def _identity(result):
    """What ran, as constant CSV columns (a CSV that lost its command line
    still says how it was made): method, scheme (empty for a method
    without one), τ and seed."""
    p = result.provenance
    scheme = p.method_options.get("scheme")
    n = len(result.values) if result.layout == "map" else len(result.t)
    return {"method": [p.method] * n,
            "scheme": [scheme.get("name", "") if isinstance(scheme, dict) else ""] * n,
            "tau": [p.tau] * n, "seed": ["" if p.seed is None else p.seed] * n}


def _savefig(fig, path):
    """Save ``fig`` to ``path`` in the format its suffix names (PNG without
    one), through :func:`varint.files.output_file` (no symbolic link
    followed)."""
    fmt = Path(path).suffix[1:].lower() or "png"
    with output_file(path, "wb") as f:
        fig.savefig(f, format=fmt, dpi=130)


def _outputs(result, args, **plot_kwargs):
    from .tables import columns

    cols = columns(result)
    _print_table(cols)
    if args.csv is not None:
        _write_csv(args.csv, {**cols, **_identity(result)})
    if args.png is not None:
        _save_plot(result, args.png, **plot_kwargs)


class _Interrupted(Exception):
    """Ctrl-C ended a run that returned its outputs so far (exit 130)."""


# -- subcommands -------------------------------------------------------------------
def _cmd_schemes(args):
    from .schemes import registered

    _check_outputs(args)
    cols = {"name": [], "order": [], "nominal": [], "forces/step": [], "corrector": [],
            "reference": []}
    for s in registered(2):
        for key, value in zip(cols, (s.name, s.order, s.nominal_order or "-",
                                     s.force_evaluations, "yes" if s.corrector else "no",
                                     s.reference.split(",")[0] or "-"), strict=True):
            cols[key].append(value)
    print(f"{'name':10} {'order':>5} {'nominal':>9} {'forces/step':>11} {'corrector':>9}  "
          "reference")
    for row in zip(*cols.values(), strict=True):
        print(f"{row[0]:10} {row[1]:>5} {row[2]:>9} {row[3]:>11} {row[4]:>9}  {row[5]}")
    print("order: of the energy error for H = p^2/2 + V(q); forces/step: gradient "
          "evaluations per step in a long run (the cost)")
    if args.csv is not None:
        _write_csv(args.csv, cols)


def _method_options(args):
    out = {"method": args.method}
    # Only options every method documents are passed (a scheme for "tm" and
    # the TDH methods); the method refuses a scheme it does not take.
    if args.scheme is not None:
        out["scheme"] = args.scheme
    # Options of some methods only (the two-particle method's separation
    # and renormalisation rule, the TM method's compensated summation): each
    # goes to the methods whose propagator lists it in OPTIONS
    # (varint.METHODS), and is refused for the others.
    from .methods import METHODS, propagator_class

    for name in ("d0", "d_max", "compensated"):
        value = getattr(args, name)
        if value is None:
            continue
        takers = [m for m in METHODS if name in propagator_class(m).OPTIONS]
        if args.method not in takers:
            raise ValueError(f"--{name.replace('_', '-')} applies to "
                             f"{', '.join('--method ' + m for m in takers)} only, not "
                             f"{args.method}")
        out[name] = value
    return out


def _indicator_options(args, model):
    """The indicator's options from --k, and the number of deviation
    vectors the run carries (the indicator's own count, for the memory
    check). --k goes to the indicator's option ``k`` (GALI orders) or to
    the option that states its number of vectors (``n_exponents``)."""
    from .indicators import INDICATORS, resolve

    indicator, fixed = resolve(args.indicator)
    options = {}
    if args.k is not None:
        name = "k" if "k" in indicator.options else indicator.count_option
        if name is None or name in fixed:
            # Sorted: the registry's order depends on which modules were
            # imported first, and the message must not.
            takers = sorted(n for n, i in INDICATORS.items() if "k" in i.options or i.count_option)
            raise ValueError(f"--k applies to {', '.join(takers)}, not {args.indicator}")
        values = _ints(args.k, "--k", None if name == "k" else 1, 1, model.dim)
        options[name] = values[0] if len(values) == 1 else tuple(values)
    try:
        configured = indicator.configure(model, {**fixed, **options})
    except ValueError as exc:
        raise ValueError(f"--k: {exc}" if options else str(exc)) from None
    return options, indicator.vectors(model, configured, None)


def _cmd_run(args):
    from .run import prepare

    _check_outputs(args)
    model, x0 = _model(args)
    tau = _tau(args, model)
    # The command's limits on the horizon, before anything runs; with the
    # automatic step they are checked again once the pilot has chosen it.
    steps = _steps(args, tau)
    x0 = _state(args, model, x0)
    kind_options, k = _indicator_options(args, model)
    n_out = args.t_out or 10 * math.ceil(math.log10(steps) + 1)
    _check_run_size(model, k, n_out, f"a run of {k} vectors of {model.name} with {n_out} "
                    "outputs")
    # After the checks that need no kernel: a run refused for its size
    # compiles nothing.
    _check_kernels(model, x0)
    opts = dict(_method_options(args), t_out=args.t_out, progress=None,
                checkpoint=args.checkpoint)
    if args.indicator != "integrate":
        opts["seed"] = args.seed
    # A pilot that finds no step warns; if the run then fails, its error
    # says why (the orbit escapes, V is singular) and the note is dropped.
    with warnings.catch_warnings(record=True) as notes:
        job = prepare(model, x0, args.indicator, args.t_end, tau, **kind_options, **opts)
    if tau is None:
        _steps(args, job.tau)
    r = job.execute()
    for note in notes:
        warnings.showwarning(note.message, note.category, note.filename, note.lineno)
    if r.interrupted and len(r.t) == 0:
        raise KeyboardInterrupt
    print(r.summary())
    _outputs(r, args)
    if r.interrupted:
        raise _Interrupted(f"interrupted at t = {float(r.t[-1]):g}: the {len(r.t)} outputs "
                           "computed so far are shown" + (" and written" if args.csv or args.png
                                                         else "")
                           + (f"; run the same command again to resume from {args.checkpoint}"
                              if args.checkpoint else ""))


def _steps(args, tau):
    """The run's steps of ``tau``, with --t-end and --t-out checked against
    them. For the automatic step (None), before its pilot has run: --t-end
    against the largest step the pilot may choose, and the steps at
    τ = 0.05 as an estimate (for the number of default output times); the
    run is checked again with the step chosen."""
    if tau is None:
        from .stepsize import FALLBACK_TAU, TAU_MAX

        t_end = check.positive_float(args.t_end, "--t-end")
        if t_end / TAU_MAX > MAX_STEPS:
            raise ValueError(f"--t-end {t_end:g} takes more than the {MAX_STEPS:.0e} steps a "
                             f"command runs even at the largest automatic step ({TAU_MAX:g}); "
                             "use a shorter --t-end")
        return max(1, round(t_end / FALLBACK_TAU))
    _, _, steps = _horizon(args.t_end, tau)
    t_out = getattr(args, "t_out", None)  # a map has none
    if t_out is not None and t_out > steps:
        raise ValueError(f"--t-out {t_out} asks for more output times than the run has "
                         f"steps (--t-end / --tau = {steps})")
    return steps


def _tau(args, model):
    """--tau; else, for a flow, None: the library's default (the step a
    pilot chooses for the splitting methods, :mod:`varint.stepsize`;
    τ = 0.05 for the others); for a map, one iteration."""
    from .run import default_tau

    if args.tau is not None:
        return args.tau
    return default_tau(model) if getattr(model, "kind", "flow") == "map" else None


#: --u and --v of a chaos map when they are not given: the paper's
#: Hénon–Heiles section, or a built-in map's whole phase space.
_DEFAULT_AXES = {None: ("-0.45:0.7:100", "-0.45:0.45:100"),
                 "standard": ("0:6.283185307179586:100", "-3.141592653589793:3.141592653589793:100"),
                 "coupled": ("0:1:100", "0:1:100")}


def _grid(args, model):
    """The initial conditions of ``varint map``: a section at --energy for
    an autonomous flow, else (a map, a time-dependent flow) a grid of the
    plane of two state components (--axes)."""
    from .grids import phase_grid
    from .models.planetary import Planetary
    from .sections import section_grid

    if isinstance(model, Planetary):
        return _element_grid(args, model)
    n = model.n_dof
    built_in = getattr(args, "map", None)
    phase = _is_map(model) or model.time_dependent
    if phase and (args.u is None or args.v is None) and built_in is None:
        raise ValueError("give --u and --v: the grid of a time-dependent model is a plane of "
                         "its phase space (--axes, default q0,p0)")
    u, v = (args.u or _DEFAULT_AXES[built_in][0]), (args.v or _DEFAULT_AXES[built_in][1])
    axes = None if args.axes is None else tuple(_ints(args.axes, "--axes", 2, 0, 2 * n - 1))
    (u0, u1, nu), (v0, v1, nv) = _grid_spec(u, "--u"), _grid_spec(v, "--v")
    # The grid's states, the potential's temporaries and the map's results:
    # about 8 (6 + 8 N) bytes per point.
    check.check_memory(check.array_bytes((nu, nv, 6 + 8 * n)),
                       f"a grid of {nu} x {nv} = {nu * nv} points (--u, --v)")
    us, vs = np.linspace(u0, u1, nu), np.linspace(v0, v1, nv)
    if phase:
        what = "a map" if _is_map(model) else "a time-dependent model"
        _refuse_unused(args, ("energy", "plane"), f"does not apply to {what}, whose chaos map is a "
                       "grid of a plane of its phase space (--u, --v on --axes)")
        default = (0, 1) if _is_map(model) else (0, n)
        return phase_grid(model, us, vs, axes=default if axes is None else axes)
    if args.energy is None:
        raise ValueError("--energy is required: the map is a grid on the section at that energy")
    # Points where V overflows are outside the energy surface; no warning.
    with np.errstate(over="ignore", invalid="ignore"):
        return section_grid(model, args.energy, us, vs, axes=axes,
                            plane=0 if args.plane is None else args.plane)


def _element_grid(args, model):
    """The grid of ``varint map --model planetary``: the outer planet's
    orbital elements on --axes (default a, e), the others fixed at
    Jupiter's and Saturn's (:data:`varint.models.planetary.JUPITER_SATURN`)."""
    from .element_grid import element_grid
    from .models.planetary import ELEMENTS, JUPITER_SATURN

    _refuse_unused(args, ("energy", "plane"), "does not apply to --model planetary, whose "
                   "chaos map is a grid of the outer planet's orbital elements (--u, --v on "
                   "--axes)")
    axes = ("a", "e") if args.axes is None else tuple(_items(args.axes, "--axes"))
    if len(axes) != 2 or axes[0] == axes[1] or any(a not in ELEMENTS for a in axes):
        raise ValueError(f"--axes: two different orbital elements among {', '.join(ELEMENTS)} "
                         f"for --model planetary, got {args.axes!r}")
    (u0, u1, nu), (v0, v1, nv) = (_grid_spec(args.u or "7:10:100", "--u"),
                                  _grid_spec(args.v or "0:0.5:100", "--v"))
    check.check_memory(check.array_bytes((nu, nv, 6 + 8 * model.n_dof)),
                       f"a grid of {nu} x {nv} = {nu * nv} points (--u, --v)")
    return element_grid(model, JUPITER_SATURN, model.n_planets, np.linspace(u0, u1, nu),
                        np.linspace(v0, v1, nv), axes=axes)


def _cmd_map(args):
    from .maps import chaos_map

    _check_outputs(args)
    if args.checkpoint is not None:
        _check_directory(args.checkpoint, "--checkpoint")
    model, _ = _model(args)
    tau = _tau(args, model)
    t_end = args.t_end
    _steps(args, tau)
    grid = _grid(args, model)
    if grid.states.size:
        _check_kernels(model, grid.states[0], "the first grid point")
    threshold = "default"
    if args.threshold is not None:
        threshold = None if args.threshold.strip().lower() == "none" else _floats(
            args.threshold, "--threshold", 1)[0]
    client = _client(args.scheduler) if args.scheduler is not None else None
    try:
        r = chaos_map(model, grid, args.indicator, t_end=t_end, tau=tau,
                      **_method_options(args), threshold=threshold, seed=args.seed,
                      chunk_size=args.chunk_size, client=client, checkpoint=args.checkpoint,
                      progress=None)
    finally:
        if client is not None:
            client.close()
    with np.errstate(invalid="ignore"):
        finite = r.values[np.isfinite(r.values)]
    where = (f"on q{grid.plane} = 0 at H = {args.energy:g}" if grid.plane is not None else
             f"over the outer planet's {grid.axes[0]}, {grid.axes[1]}"
             if isinstance(grid.axes[0], str) else
             f"on the plane of state components {grid.axes[0]}, {grid.axes[1]}")
    p = r.provenance
    scheme = p.method_options.get("scheme")
    print(f"{r.indicator} map of {model.name} {where}: "
          f"{len(r.values)} orbits ({grid.mask.size} grid points), t_end = {t_end:g}, "
          f"method {p.method}" + (f", scheme {scheme['name']}" if isinstance(scheme, dict)
                                  else "")
          + f", tau = {p.tau:g} ({_tau_rule(p)}), {p.wall_time:.3g} s")
    print(f"decided early: {int(r.decided.sum())}, failed: {int((r.status > 0).sum())}"
          + (f", below {r.threshold:g}: {int((finite < r.threshold).sum())}"
             if r.threshold is not None else "")
          + (f"; value quartiles {np.percentile(finite, [25, 50, 75]).round(6).tolist()}"
             if finite.size else ""))
    if args.csv is not None:
        from .tables import columns

        _write_csv(args.csv, {**columns(r), **_identity(r)})
    if args.png is not None:
        _save_plot(r, args.png)
    if r.interrupted:
        raise _Interrupted("interrupted: the chunks finished so far are shown"
                           + (f"; run the same command again to resume from {args.checkpoint}"
                              if args.checkpoint else ""))


def _tau_rule(provenance):
    """How τ was chosen, in a few words."""
    choice = provenance.tau_choice or {}
    rule = choice.get("rule", "given")
    if rule == "pilot":
        return f"chosen by a pilot to energy error {choice['tolerance']:.0e}"
    return {"given": "given", "fixed": "the method's default",
            "fallback": "the fallback: no step met the pilot's tolerance"}.get(rule, rule)


def _check_directory(value, flag):
    """A directory the command may create (its parent must exist)."""
    if not value.strip():
        raise ValueError(f"{flag} must name a directory, got {value!r}")
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{flag} {value} is a file; expected a directory")
    if not path.exists() and not path.parent.is_dir():
        raise ValueError(f"{flag} {value}: directory {path.parent} does not exist")


def _client(address):
    try:
        from distributed import Client
    except ImportError:
        raise ImportError("--scheduler needs dask.distributed: pip install "
                          "'varint[dask]'") from None
    if not address.strip():
        raise ValueError("--scheduler must be an address such as tcp://host:8786, got ''")
    try:
        return Client(address, timeout=30)
    except (OSError, ValueError, TypeError) as exc:
        raise ValueError(f"cannot connect to --scheduler {address}: {check.first_line(exc)}") from None


def _cmd_select(args):
    from .selection import select_scheme

    _check_outputs(args)
    model, x0 = _model(args)
    x0 = _state(args, model, x0)
    _check_kernels(model, x0)
    choice = select_scheme(model, x0, args.target, metric=args.metric, t_end=args.t_end,
                           pilot_t=_pilot_t(args))
    print(choice)
    print(f"chosen: method={choice.method} scheme={choice.scheme} tau={choice.tau:g}")
    if args.csv is not None:
        _write_csv(args.csv, {key: [row[key] for row in choice.table] for key in choice.table[0]})


def _pilot_t(args):
    """--pilot-t, or select_scheme's default min(t_end, 100) rounded down to
    4 times a multiple of every candidate tau, as the pilots need (the
    unrounded default fails for e.g. --t-end 10)."""
    from .selection import DEFAULT_TAUS

    if args.pilot_t is not None:
        return args.pilot_t
    unit = 4 * max(DEFAULT_TAUS)
    pilot = math.floor(min(args.t_end, 100.0) / unit + 1e-9) * unit
    if pilot == 0:
        raise ValueError(f"--t-end {args.t_end:g} is shorter than the shortest pilot, {unit:g} "
                         "(4 steps of the largest candidate tau)")
    return pilot


# -- lattices ----------------------------------------------------------------------
def _lattice_shape(text):
    """argparse type: N (a chain) or NXxNY (a square lattice)."""
    parts = text.lower().split("x")
    if len(parts) > 2:
        raise argparse.ArgumentTypeError(f"expected N or NXxNY, got {_shown(text)}")
    values = [_integer(v, 2, "N or NXxNY with sides >= 2") for v in parts]
    return values[0] if len(values) == 1 else tuple(values)


def _seed_list(text):
    """argparse type: one seed, a comma-separated list, or FIRST:LAST."""
    if ":" in text:
        first, _, last = text.partition(":")
        lo, hi = _natural(first), _natural(last)
        if hi < lo:
            raise argparse.ArgumentTypeError(f"expected FIRST:LAST with LAST >= FIRST, got "
                                             f"{_shown(text)}")
        return list(range(lo, hi + 1))
    return [_natural(v) for v in text.replace(",", " ").split()] or \
        _natural(text)  # an empty list: let _natural name the value


def _lattice_model(args):
    """The registered lattice (:mod:`varint.models.registry`) and its
    parameters from the lattice options; the factory takes ``seed=``."""
    from .models.registry import get_model

    entry = get_model(args.model)
    values = {}
    for option, users in _parameter_options(_lattices()).items():
        value = getattr(args, option[2:].replace("-", "_"))
        takes = [par for e, par in users if e is entry]
        if value is not None and not takes:
            raise ValueError(f"{option} does not apply to --model {args.model}")
        if takes:
            values[takes[0].name] = takes[0].default if value is None else value
    params = {"shape": args.sites, "boundary": args.boundary, **values}
    if args.model == "fput" and not isinstance(args.sites, int):
        raise ValueError(f"--model fput is a chain: --sites must be one integer, got "
                         f"{args.sites[0]}x{args.sites[1]}")
    return entry.factory, params


def _lattices():
    from .models.registry import MODELS

    return [e for e in MODELS.values() if e.kind == "lattice"]


def _cmd_lattice(args):
    from .ensemble import ensemble

    _check_outputs(args)
    if args.checkpoint is not None:
        _check_directory(args.checkpoint, "--checkpoint")
    t_end, tau, steps = _horizon(args.t_end, args.tau)
    factory, params = _lattice_model(args)
    seeds = args.seeds if isinstance(args.seeds, list) else [args.seeds]
    if args.model == "fput" and len(seeds) > 1:
        raise ValueError("--model fput has no disorder: give one --seeds value")
    first = factory(**params, seed=seeds[0])

    def x0(model, seed):
        kwargs = {} if args.density is None else {"density": args.density}
        return model.initial_block(args.block, seed=seed, **kwargs)

    x0(first, seeds[0])  # a bad --block or --density before any run
    # The schemes D19 found most efficient at moderate accuracy.
    scheme = args.scheme or ("s9ABC6" if args.model == "ddnls" else "ABA864")
    opts = {"scheme": scheme}
    if args.t_out is not None:
        if args.t_out > steps:
            raise ValueError(f"--t-out {args.t_out} asks for more output times than the run "
                             f"has steps (--t-end / --tau = {steps})")
        opts["t_out"] = args.t_out
    r = ensemble(factory, seeds, x0, args.indicator, t_end, tau, params=params,
                 checkpoint=args.checkpoint, progress=None, **opts)
    names = ["m2", "participation"] + (["x1", "dvd_participation"]
                                       if args.indicator == "dvd" else [])
    cols = {"t": r.t}
    for name in names:
        mean, std, _ = r.log_mean(name)
        cols[f"<log10 {name}>"] = mean
        if len(seeds) > 1:
            cols[f"std {name}"] = std
    print(f"{first.name.split('(')[0]} {params}, {len(seeds)} realisation(s), "
          f"scheme {scheme}, tau {tau:g}: "
          f"max |dH/H| {np.nanmax(np.abs(r.energy_error)):.2g}")
    _print_table(cols)
    if r.t.size >= 3 and r.t[-1] >= 100 * r.t[0]:
        window = (r.t[-1] / 100, r.t[-1])
        for name in names[:1] + names[2:3]:
            fit = r.exponent(name, window)
            print(f"{name} ~ t^{fit['a']:.3f} over t = {window[0]:.3g}..{window[1]:.3g}"
                  + (f" (single realisations: {fit['a_mean']:.3f} +- {fit['a_std']:.3f})"
                     if fit["realisations"] > 1 else ""))
    if args.csv is not None:
        _write_csv(args.csv, cols)
    if args.png is not None:
        _plot_lattice(r, args.png)
    if r.interrupted:
        raise _Interrupted(f"interrupted: {int((r.status != -2).sum())} of {len(seeds)} "
                           "realisations finished" + (f"; run the same command again to "
                                                      f"resume from {args.checkpoint}"
                                                      if args.checkpoint else ""))


def _plot_lattice(r, path):
    """The ensemble's panels (:func:`varint.plotting.plot_ensemble`):
    ⟨log₁₀⟩ of each series against t, log–log, its spread shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plotting import plot_ensemble

    fig = plot_ensemble(r)[0].figure
    try:
        _savefig(fig, path)
    except OSError as exc:
        raise OSError(f"cannot write --png {path}: {exc.strerror or exc}") from exc
    finally:
        plt.close(fig)
    print(f"plot written to {path}")


def _add_lattice_parser(sub):
    p = sub.add_parser("lattice", help="a disordered lattice (KG, DDNLS) or FPUT chain: "
                       "spreading and chaos, one or many realisations",
                       description="Excite a central block of a lattice and follow the "
                       "spreading of its energy (KG, FPUT) or norm (DDNLS) (indicator "
                       "'spreading': m2, participation number) and its chaos ('dvd': also the "
                       "finite-time mLCE and the deviation vector distribution). Several "
                       "--seeds run an ensemble over disorder: the table gives <log10> and its "
                       "spread over the realisations, and the exponents over the last two "
                       "decades.")
    p.add_argument("indicator", choices=("spreading", "dvd"), help="what to compute")
    lattices = _lattices()
    p.add_argument("--model", choices=[e.name for e in lattices], required=True,
                   help="; ".join(f"{e.name}: {e.summary}" for e in lattices))
    p.add_argument("--sites", type=_lattice_shape, required=True,
                   help="N (a chain) or NXxNY (a square lattice; kg and ddnls)")
    p.add_argument("--boundary", choices=("fixed", "periodic"), default="fixed",
                   help="ends (default fixed)")
    for option, users in _parameter_options(lattices).items():
        p.add_argument(option, type=_finite, help="; ".join(
            f"{entry.name}: {par.doc} (default {par.default:g})" for entry, par in users))
    p.add_argument("--seeds", type=_seed_list, default=[1],
                   help="disorder realisations: S, S1,S2,... or FIRST:LAST (default 1)")
    p.add_argument("--block", type=_count, default=1,
                   help="width of the excited central block (default 1 site)")
    p.add_argument("--density", type=_positive, help="energy (kg, fput) or norm (ddnls) per "
                   "excited site (default: the model's)")
    p.add_argument("--t-end", type=_positive, default=1e3, help="final time (default 1e3)")
    p.add_argument("--tau", type=_positive, default=0.1, help="step (default 0.1)")
    p.add_argument("--scheme", help="splitting scheme (default ABA864 for kg and fput, the "
                   "three-part s9ABC6 for ddnls); see 'varint schemes'")
    p.add_argument("--t-out", type=_count, default=None, help="number of output times "
                   "(default: log-spaced, 10 per decade)")
    p.add_argument("--checkpoint", metavar="DIR", help="keep finished realisations in DIR and "
                   "resume from them")
    p.add_argument("--csv", metavar="FILE", help="write the table to FILE")
    p.add_argument("--png", metavar="FILE", help="plot to FILE")
    p.set_defaults(handler=_cmd_lattice)


# -- studies (from a source checkout) ------------------------------------------------
#: Where to get a checkout with the studies, for the message when none is found.
REPOSITORY_HINT = ("get a source checkout (clone the varint repository with git) and run "
                   "'varint study' from inside it")


def _is_checkout(folder):
    """Whether ``folder`` is a varint source tree: studies/ beside a
    pyproject.toml whose project is varint."""
    try:
        text = (folder / "pyproject.toml").read_text(errors="replace")
    except OSError:
        return False
    return (folder / "studies").is_dir() and re.search(
        r"""(?m)^\s*name\s*=\s*["']varint["']""", text) is not None


def find_checkout(start=None):
    """The varint source checkout holding ``start`` (the current directory
    by default) or, failing that, the one this package was imported from
    (an editable install); None if there is none."""
    start = Path.cwd() if start is None else Path(start)
    for folder in (start.resolve(), *start.resolve().parents):
        if _is_checkout(folder):
            return folder
    own = Path(__file__).resolve().parent.parent
    return own if _is_checkout(own) else None


def _study_names(root):
    out = {}
    for path in sorted((root / "studies").glob("*.py")):
        if path.stem in ("__init__", "common"):
            continue
        text = path.read_text(errors="replace")
        if "def main(" not in text:
            continue
        out[path.stem] = _first_sentence(text.split('"""')[1] if text.startswith('"""') else "")
    return out


def _first_sentence(doc):
    """The first sentence of a docstring's first paragraph, whole (a
    listing that cuts at the end of a line stops mid-sentence)."""
    paragraph = " ".join(doc.strip().split("\n\n")[0].split())
    # reST roles and literals read as plain words in a terminal.
    paragraph = re.sub(r":\w+:`~?([^`]+)`", r"\1", paragraph).replace("``", "")
    # A sentence ends at . ! or ? before a capital letter or the end, not
    # after an abbreviation ("Figs. 2-11").
    found = re.search(r"^(.+?[.!?])(?=\s+[A-Z]|$)", paragraph)
    return found.group(1) if found else paragraph


def study_status(returned):
    """The exit status of a study whose ``main`` returned ``returned``:
    an integer is a status (``fingerprints --check`` returns 1 when a bit
    changed); anything else (most studies return their results, a dict)
    or None means it ran to the end: 0."""
    if isinstance(returned, (int, np.integer)) and not isinstance(returned, bool):
        return int(returned)
    return 0


def _cmd_study(args):
    root = find_checkout()
    if root is None:
        raise ValueError(f"no varint source checkout here ({Path.cwd()}) or above: the studies "
                         f"are not installed with the package; {REPOSITORY_HINT}")
    names = _study_names(root)
    if not names:
        raise ValueError(f"no studies in {root / 'studies'}")
    if args.name is None or args.list:
        import textwrap

        width = max(map(len, names)) + 2
        for name, doc in names.items():
            print(textwrap.fill(doc, 100, initial_indent=f"{name:{width}}",
                                subsequent_indent=" " * width))
        return
    if args.name not in names:
        raise ValueError(f"unknown study {args.name!r}; expected one of: {', '.join(names)}")
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    _forget_other_studies(root / "studies")
    module = importlib.import_module(f"studies.{args.name}")
    status = study_status(module.main(args.study_args))
    if status:
        raise SystemExit(status)


def _forget_other_studies(folder):
    """Drop a ``studies`` package imported from another folder (another
    checkout, in the same process): the study must come from ``folder``."""
    loaded = sys.modules.get("studies")
    paths = [Path(p).resolve() for p in getattr(loaded, "__path__", [])]
    if loaded is None or Path(folder).resolve() in paths:
        return
    for name in [n for n in sys.modules if n == "studies" or n.startswith("studies.")]:
        del sys.modules[name]


def _cmd_demo(args):
    from .demo import run

    if args.out:  # '' means no plot
        _check_plot_format(check.output_file(args.out, "--out"), "--out")
    t_end, tau, _ = _horizon(args.t_end, args.tau)
    run(t_end, tau, args.scheme, args.out)


def _add_run_options(p, t_end=1e4, chaos_map=False):
    p.add_argument("--t-end", type=_positive, default=t_end,
                   help=f"final time (default {t_end:g})")
    p.add_argument("--tau", type=_positive, default=None, help="step / renormalisation "
                   "interval (default: for tm, the largest step whose energy error over a "
                   "short pilot run meets the tolerance; 0.05 for the other methods; for a "
                   "map, iterations per interval, default 1)")
    from .maps import MAP_SCHEME
    from .methods import MAP_METHODS, METHODS
    from .schemes import DEFAULT_SCHEME

    p.add_argument("--method", default="tm", help=f"integration method: {', '.join(METHODS)} "
                   f"(default tm; a symplectic map: {', '.join(MAP_METHODS)})")
    default = (f"{MAP_SCHEME} when the step is chosen automatically (no --tau), else "
               f"{DEFAULT_SCHEME}" if chaos_map else
               f"{DEFAULT_SCHEME}, or a lattice's own: ABA864 for KG and FPUT, s11ABC6 for DDNLS")
    p.add_argument("--scheme", help=f"splitting scheme (default {default}); see "
                   "'varint schemes'")
    p.add_argument("--compensated", nargs="?", const=True, default=None, type=_compensation,
                   metavar="LEVEL", help="tm: add every drift and kick by compensated (Kahan) "
                   "summation, a lower round-off floor at a higher cost per step; 'orbit': "
                   "the orbit's drifts and kicks only; 'step': the orbit's displacement once "
                   "per step (the cheapest)")
    p.add_argument("--d0", type=_positive, default=None, help="two-particle: separation of "
                   "each neighbour after it is put back (default 1e-8)")
    p.add_argument("--d-max", type=_positive, default=None, help="two-particle: put a "
                   "neighbour back only once its separation exceeds D_MAX (> --d0; default: "
                   "every interval)")
    p.add_argument("--seed", type=_natural, default=0,
                   help="seed of the random deviation vectors (an integer >= 0)")


def build_parser():
    """The argument parser of the ``varint`` command."""
    from .indicators import indicator_names

    parser = _Parser(prog="varint", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--traceback", action="store_true",
                        help="on an error, also print the traceback (for bug reports)")
    sub = parser.add_subparsers(dest="command", title="commands", metavar="COMMAND")

    p = sub.add_parser("schemes", help="list the splitting schemes with their order and cost",
                       description="List the registered splitting schemes: order of the energy "
                       "error, published order, gradient evaluations per step, corrector.")
    p.add_argument("--csv", metavar="FILE", help="also write the table to FILE")
    p.set_defaults(handler=_cmd_schemes)

    p = sub.add_parser("run", help="an indicator (or a plain integration) of one orbit",
                       description="Run an indicator for a paper orbit or a model, print its "
                       "values at up to 12 of the output times, and optionally write them "
                       "all (CSV) and a plot (PNG).")
    p.add_argument("indicator", choices=indicator_names(), help="what to compute: any "
                   "registered indicator (varint.INDICATORS); x1 is the largest Lyapunov "
                   "exponent alone")
    _add_model_arguments(p, maps=True)
    _add_state_arguments(p)
    _add_run_options(p)
    p.add_argument("--k", help="lyapunov: number of exponents; gali: orders, e.g. 2,3,4")
    p.add_argument("--t-out", type=_count, default=None, help="number of output times "
                   "(default: log-spaced, 10 per decade)")
    p.add_argument("--checkpoint", metavar="FILE", help="save the run to FILE every minute "
                   "and when it stops (Ctrl-C included); the same command again resumes it, "
                   "bit for bit")
    p.add_argument("--csv", metavar="FILE", help="write every output to FILE")
    p.add_argument("--png", metavar="FILE", help="plot to FILE")
    p.set_defaults(handler=_cmd_run)

    p = sub.add_parser("map", help="a chaos map of a grid on a surface of section",
                       description="Evaluate an indicator (final SALI, GALI_k, X1, MEGNO, FLI or "
                       "OFLI) on a grid "
                       "of a surface of section q[plane] = 0 at fixed energy, with p[plane] >= "
                       "0 solved from it, locally on all cores or on a Dask cluster.")
    _add_model_arguments(p, orbit=False, maps=True)
    p.add_argument("--energy", type=_finite, help="energy of the section (required for an "
                   "autonomous flow; maps and time-dependent models take a grid of a plane of "
                   "their phase space instead)")
    p.add_argument("--plane", type=_natural, default=None, help="coordinate index of the "
                   "section (default 0: x = 0)")
    p.add_argument("--axes", help="state indices of the grid axes (default: the next coordinate "
                   "and its momentum, 1,3 = y,py for 2 dof; 0,1 for a map; q0,p0 for a "
                   "time-dependent model; --model planetary: two orbital elements of the "
                   "outer planet, default a,e)")
    p.add_argument("--u", default=None, help="first axis START:STOP:NUM "
                   "(default -0.45:0.7:100; a built-in map's whole range; --model planetary: "
                   "7:10:100 in a)")
    p.add_argument("--v", default=None, help="second axis START:STOP:NUM "
                   "(default -0.45:0.45:100; a built-in map's whole range; --model planetary: "
                   "0:0.5:100 in e)")
    p.add_argument("--indicator", default="sali", help="sali (default), gali, gali_K, x1, "
                   "megno, fli, ofli")
    _add_run_options(p, t_end=1e3, chaos_map=True)
    p.add_argument("--threshold", help="early-stopping threshold, or 'none' (default: the "
                   "indicator's, 1e-8 for SALI)")
    p.add_argument("--chunk-size", type=_count, default=None, help="orbits per chunk")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler, e.g. "
                   "tcp://host:8786")
    p.add_argument("--checkpoint", metavar="DIR", help="keep finished chunks in DIR and resume "
                   "from them")
    p.add_argument("--csv", metavar="FILE", help="write one row per orbit to FILE")
    p.add_argument("--png", metavar="FILE", help="plot the map to FILE")
    p.set_defaults(handler=_cmd_map)

    p = sub.add_parser("select", help="the cheapest method, scheme and step for a target error",
                       description="Pilot integrations of the TM method with several schemes "
                       "and steps against the cached Taylor reference; prints the table and "
                       "the cheapest choice that meets the target at t_end.")
    _add_model_arguments(p)
    _add_state_arguments(p)
    p.add_argument("--target", type=_positive, required=True, help="largest acceptable error")
    p.add_argument("--metric", default="energy", choices=("energy", "tangent", "X1"),
                   help="what the error measures (default energy)")
    p.add_argument("--t-end", type=_positive, default=1e4, help="horizon of the job "
                   "(default 1e4)")
    p.add_argument("--pilot-t", type=_positive, default=None, help="pilot horizon (default "
                   "min(t_end, 100))")
    p.add_argument("--csv", metavar="FILE", help="write the table to FILE")
    p.set_defaults(handler=_cmd_select)

    _add_lattice_parser(sub)

    p = sub.add_parser("study", help="run a study of studies/ (paper reproduction, "
                       "benchmarks)", description="Run studies/NAME.py of the varint source "
                       "checkout that holds the current directory (the studies are not "
                       "installed with the package); arguments after NAME go to the study "
                       "(e.g. --quick).")
    p.add_argument("name", nargs="?", help="the study; omit (or --list) to list them")
    p.add_argument("--list", action="store_true", help="list the studies")
    p.add_argument("study_args", nargs=argparse.REMAINDER, help="arguments of the study")
    p.set_defaults(handler=_cmd_study)

    from .demo import add_arguments

    p = sub.add_parser("demo", help="the demo: R1 and C1 spectra and GALIs (python -m varint)",
                       description="Lyapunov spectra and GALIs of the paper's R1 and C1, "
                       "printed and plotted; the same as 'python -m varint'.")
    add_arguments(p)
    p.set_defaults(handler=_cmd_demo)
    for p in sub.choices.values():
        # Also after the command (varint run ... --traceback); SUPPRESS keeps
        # the value given before it when this one is absent.
        p.add_argument("--traceback", action="store_true", default=argparse.SUPPRESS,
                       help="on an error, also print the traceback")
    return parser


# -- errors ----------------------------------------------------------------------------
def main(argv=None):
    """Entry point of the ``varint`` console script; returns the exit status.

    Every failure ends in one line on stderr: 2 for bad arguments, 1 for a
    failed run or an internal error, 130 after Ctrl-C. With ``--traceback``
    the traceback is printed before that line.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, or a one-line argument error already printed
        return exc.code
    if args.command is None:
        parser.print_help()
        return 0
    prog = f"varint {args.command}"
    with warnings.catch_warnings():
        warnings.showwarning = _warning_printer(prog)
        # A run stopped by Ctrl-C says so in the command's own last line.
        warnings.filterwarnings("ignore", message="interrupted at", category=RuntimeWarning)
        try:
            args.handler(args)
        except SystemExit as exc:  # a study's own exit status (its message is printed)
            return exc.code
        except BaseException as exc:  # noqa: BLE001 - every failure becomes one line
            if isinstance(exc, BrokenPipeError):
                _silence_stdout()
                return 0
            status, message = _failure(exc)
            if args.traceback:
                traceback.print_exception(exc)
            print(f"{prog}: {message}", file=sys.stderr)
            return status
    return 0


def _failure(exc):
    """(exit status, one-line message) for an exception out of a command."""
    from numba.core.errors import NumbaError

    from .driver import IntegrationError

    text = _one_line(exc)
    if isinstance(exc, _Interrupted):
        return 130, text
    if isinstance(exc, KeyboardInterrupt):
        return 130, "interrupted"
    if isinstance(exc, IntegrationError):
        return 1, f"run failed: {text}"
    if isinstance(exc, ValueError):
        return 2, f"error: {text}"
    if isinstance(exc, ModuleNotFoundError) and exc.name:
        return 2, f"error: this needs the package {exc.name}, which is not installed ({text})"
    if isinstance(exc, ImportError):
        return 2, f"error: {text}"
    if isinstance(exc, MemoryError):
        return 1, f"run failed: out of memory ({text or 'MemoryError'})"
    if isinstance(exc, ArithmeticError):
        return 1, (f"run failed: {type(exc).__name__} in the model's kernels or the "
                   f"indicator ({text}); the orbit may have reached a singular point of the "
                   "potential")
    if isinstance(exc, NumbaError) or isinstance(exc.__cause__, NumbaError):
        return 1, (f"run failed: numba could not compile the integrator: {check.first_line(exc)}; "
                   "rerun with 'varint --traceback ...' for the details")
    if isinstance(exc, OSError):
        return 1, f"error: {text}"
    return 1, (f"internal error: {type(exc).__name__}: {text}; rerun with "
               "'varint --traceback ...' to see where, and please report it")


def _warning_printer(prog):
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{prog}: warning: {_one_line(message)}", file=file or sys.stderr)
    return show


def _silence_stdout():
    # Piped into e.g. head: the reader has gone. Point stdout at /dev/null so
    # the interpreter's final flush does not report the broken pipe again.
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def _one_line(exc):
    return " ".join(str(exc).split())


if __name__ == "__main__":
    sys.exit(main())
