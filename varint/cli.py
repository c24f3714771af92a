"""The ``varint`` command line: the common jobs without writing Python.

    varint schemes                          the splitting schemes, order, cost
    varint run lyapunov --orbit R1          an indicator for a paper orbit or
    varint run sali --potential "..."       a model given as a potential
    varint map --energy 0.125 ...           a chaos map of a surface of section
    varint select --orbit R1 --target 1e-8  the cheapest scheme and step
    varint study stress --quick             a study of studies/ (source tree)
    varint demo                             R1 and C1, as ``python -m varint``

Results are printed as a table; ``--csv`` and ``--png`` write them to files.
Bad arguments and failed runs end with a one-line error (exit status 2 for
arguments, 1 for a failed run).
"""

from __future__ import annotations

import argparse
import csv
import importlib
import sys
from pathlib import Path

import numpy as np

__all__ = ["main"]

INDICATORS = ("lyapunov", "gali", "sali", "megno", "integrate")
MODELS = ("henon-heiles", "three-dof", "fpu-beta")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (instead of usage + error)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _floats(text, name, count=None):
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{name} must be comma-separated numbers, got {text!r}") from None
    if count is not None and len(values) != count:
        raise ValueError(f"{name} needs {count} numbers, got {len(values)} ({text!r})")
    return values


def _grid(text, name):
    """START:STOP:NUM as a linspace."""
    parts = text.split(":")
    try:
        start, stop, num = float(parts[0]), float(parts[1]), int(parts[2])
    except (ValueError, IndexError):
        raise ValueError(f"{name} must be START:STOP:NUM, e.g. -0.5:0.7:200, got {text!r}") \
            from None
    if len(parts) != 3 or num < 1 or not stop > start:
        raise ValueError(f"{name} must be START:STOP:NUM with STOP > START and NUM >= 1, "
                         f"got {text!r}")
    return np.linspace(start, stop, num)


# -- models and initial states -------------------------------------------------
def _add_model_arguments(p, orbit=True):
    group = p.add_argument_group("model (one of)")
    if orbit:
        group.add_argument("--orbit", help="a paper orbit: R1, C1, C2, R2 or R3 (model and x0)")
    group.add_argument("--model", choices=MODELS,
                       help="a built-in model (fpu-beta: with --fpu-n and --beta)")
    group.add_argument("--potential", metavar="EXPR",
                       help="V(q) as a SymPy expression, e.g. '(x**2+y**2)/2 + x**2*y - y**3/3'")
    group.add_argument("--coords", metavar="NAMES",
                       help="the coordinates of --potential in order, e.g. x,y")
    group.add_argument("--inverse-mass", metavar="M", help="diagonal of M^-1 (default all 1)")
    group.add_argument("--fpu-n", type=int, default=8, help="FPU particles (default 8)")
    group.add_argument("--beta", type=float, default=1.5, help="FPU beta (default 1.5)")


def _add_state_arguments(p):
    group = p.add_argument_group("initial state (with --model or --potential)")
    group.add_argument("--x0", metavar="Q,P", help="the full state q then p, comma-separated")
    group.add_argument("--energy", type=float, help="solve p[0] >= 0 from this energy, "
                       "with --q and --p giving the rest")
    group.add_argument("--q", metavar="Q", help="positions for --energy")
    group.add_argument("--p", metavar="P", help="momenta for --energy (p[0] is solved)")


def _model(args):
    from . import models

    given = [a for a in ("orbit", "model", "potential") if getattr(args, a, None)]
    if len(given) != 1:
        raise ValueError("give exactly one of " + ", ".join(
            f"--{a}" for a in ("orbit", "model", "potential") if hasattr(args, a))
                         + (f" (got {', '.join('--' + g for g in given)})" if given else ""))
    if given[0] == "orbit":
        return models.paper_orbit(args.orbit)
    if args.model:
        model = {"henon-heiles": lambda: models.HenonHeiles(),
                 "three-dof": lambda: models.ThreeDof(),
                 "fpu-beta": lambda: models.FPUBeta(args.fpu_n, args.beta)}[args.model]()
        return model, None
    import sympy as sp

    if not args.coords:
        raise ValueError("--potential needs --coords naming its coordinates, e.g. --coords x,y")
    names = [c.strip() for c in args.coords.split(",") if c.strip()]
    symbols = sp.symbols(names)
    try:
        V = sp.sympify(args.potential, locals=dict(zip(names, symbols)))
    except (sp.SympifyError, SyntaxError, TypeError) as exc:
        raise ValueError(f"cannot read --potential {args.potential!r}: {exc}") from None
    minv = None if args.inverse_mass is None else _floats(args.inverse_mass, "--inverse-mass",
                                                          len(names))
    return models.from_potential(V, symbols, inverse_mass=minv, name=args.potential), None


def _state(args, model, x0):
    from .models import solve_momentum

    if args.x0 is not None:
        return np.array(_floats(args.x0, "--x0", model.dim))
    if args.energy is not None:
        n = model.n_dof
        q = _floats(args.q, "--q", n) if args.q else [0.0] * n
        p = _floats(args.p, "--p", n) if args.p else [0.0] * n
        return solve_momentum(model, q, p, args.energy)
    if x0 is None:
        raise ValueError("give the initial state: --x0, or --energy with --q/--p "
                         "(or use --orbit)")
    return x0


# -- output ----------------------------------------------------------------------
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


def _write_csv(path, cols):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(cols))
        w.writerows(zip(*[np.asarray(c).tolist() for c in cols.values()]))
    print(f"table written to {path}")


def _save_plot(result, path, **kwargs):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plotting import plot

    fig, ax = plt.subplots(figsize=(6, 4.5), layout="constrained")
    plot(result, ax, **kwargs)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    print(f"plot written to {path}")


def _outputs(result, args, **plot_kwargs):
    from .tables import columns

    cols = columns(result)
    _print_table(cols)
    if args.csv:
        _write_csv(args.csv, cols)
    if args.png:
        _save_plot(result, args.png, **plot_kwargs)


# -- subcommands -------------------------------------------------------------------
def _cmd_schemes(args):
    from .schemes import SCHEMES

    cols = {"name": [], "order": [], "nominal": [], "forces/step": [], "corrector": [],
            "reference": []}
    for s in SCHEMES.values():
        for key, value in zip(cols, (s.name, s.order, s.nominal_order or "-",
                                     s.force_evaluations, "yes" if s.corrector else "no",
                                     s.reference.split(",")[0] or "-")):
            cols[key].append(value)
    print(f"{'name':10} {'order':>5} {'nominal':>9} {'forces/step':>11} {'corrector':>9}  "
          "reference")
    for row in zip(*cols.values()):
        print(f"{row[0]:10} {row[1]:>5} {row[2]:>9} {row[3]:>11} {row[4]:>9}  {row[5]}")
    print("order: of the energy error for H = p^2/2 + V(q); forces/step: gradient "
          "evaluations per step in a long run (the cost)")
    if args.csv:
        _write_csv(args.csv, cols)


def _method_options(args):
    out = {"method": args.method, "tau": args.tau}
    if args.scheme:
        out["scheme"] = args.scheme
    return out


def _cmd_run(args):
    from . import api

    model, x0 = _model(args)
    x0 = _state(args, model, x0)
    opts = dict(_method_options(args), t_out=args.t_out, progress=None)
    if args.indicator == "lyapunov":
        k = None if args.k is None else int(_floats(args.k, "--k", 1)[0])
        r = api.lyapunov_spectrum(model, x0, args.t_end, n_exponents=k, seed=args.seed,
                                         **opts)
    elif args.indicator == "gali":
        orders = tuple(int(v) for v in _floats(args.k, "--k")) if args.k else (2, model.dim)
        r = api.gali(model, x0, args.t_end, k=orders, seed=args.seed, **opts)
    elif args.indicator == "sali":
        r = api.sali(model, x0, args.t_end, seed=args.seed, **opts)
    elif args.indicator == "megno":
        r = api.megno(model, x0, args.t_end, seed=args.seed, **opts)
    else:
        r = api.integrate(model, x0, args.t_end, **opts)
    print(r.summary())
    _outputs(r, args)


def _cmd_map(args):
    from .maps import chaos_map
    from .sections import section_grid

    if args.energy is None:
        raise ValueError("--energy is required: the map is a grid on the section at that energy")
    model, _ = _model(args)
    axes = None if args.axes is None else tuple(int(v) for v in _floats(args.axes, "--axes", 2))
    grid = section_grid(model, args.energy, _grid(args.u, "--u"), _grid(args.v, "--v"),
                        axes=axes, plane=args.plane)
    threshold = "default" if args.threshold is None else (
        None if args.threshold.lower() == "none" else _floats(args.threshold, "--threshold", 1)[0])
    client = None
    if args.scheduler:
        try:
            from distributed import Client
        except ImportError:
            raise ImportError("--scheduler needs dask.distributed: pip install "
                              "'varint[dask]'") from None
        client = Client(args.scheduler)
    try:
        r = chaos_map(model, grid, args.indicator, t_end=args.t_end, tau=args.tau,
                      method=args.method, scheme=args.scheme, threshold=threshold,
                      seed=args.seed, chunk_size=args.chunk_size, client=client,
                      checkpoint=args.checkpoint, progress=None)
    finally:
        if client is not None:
            client.close()
    with np.errstate(invalid="ignore"):
        finite = r.values[np.isfinite(r.values)]
    print(f"{r.indicator} map of {model.name} on q{grid.plane} = 0 at H = {args.energy:g}: "
          f"{len(r.values)} orbits ({grid.mask.size} grid points), t_end = {args.t_end:g}, "
          f"{r.provenance.wall_time:.3g} s")
    print(f"decided early: {int(r.decided.sum())}, failed: {int((r.status > 0).sum())}"
          + (f", below {r.threshold:g}: {int((finite < r.threshold).sum())}"
             if r.threshold is not None else "")
          + (f"; value quartiles {np.percentile(finite, [25, 50, 75]).round(6).tolist()}"
             if finite.size else ""))
    if args.csv:
        from .tables import columns

        _write_csv(args.csv, columns(r))
    if args.png:
        _save_plot(r, args.png)


def _cmd_select(args):
    from .selection import select_scheme

    model, x0 = _model(args)
    x0 = _state(args, model, x0)
    choice = select_scheme(model, x0, args.target, metric=args.metric, t_end=args.t_end,
                           pilot_t=args.pilot_t)
    print(choice)
    print(f"chosen: method={choice.method} scheme={choice.scheme} tau={choice.tau:g}")
    if args.csv:
        _write_csv(args.csv, {key: [row[key] for row in choice.table] for key in choice.table[0]})


def _studies_dir():
    return Path(__file__).resolve().parent.parent / "studies"


def _study_names():
    folder = _studies_dir()
    if not folder.is_dir():
        return {}
    out = {}
    for path in sorted(folder.glob("*.py")):
        if path.stem in ("__init__", "common"):
            continue
        text = path.read_text()
        if "def main(" not in text:
            continue
        doc = text.split('"""')[1].strip().splitlines()[0] if text.startswith('"""') else ""
        out[path.stem] = doc
    return out


def _cmd_study(args):
    names = _study_names()
    if not names:
        raise ValueError(f"no studies found: they live in the source tree ({_studies_dir()}); "
                         "run varint from a checkout of the repository")
    if args.name is None or args.list:
        for name, doc in names.items():
            print(f"{name:18} {doc}")
        return 0
    if args.name not in names:
        raise ValueError(f"unknown study {args.name!r}; expected one of: {', '.join(names)}")
    root = str(_studies_dir().parent)
    if root not in sys.path:
        sys.path.insert(0, root)
    module = importlib.import_module(f"studies.{args.name}")
    module.main(args.study_args)
    return 0


def _cmd_demo(args):
    from .demo import run

    run(args.t_end, args.tau, args.scheme, args.out)


def _add_run_options(p, t_end=1e4):
    p.add_argument("--t-end", type=float, default=t_end, help=f"final time (default {t_end:g})")
    p.add_argument("--tau", type=float, default=0.05, help="step / renormalisation interval "
                   "(default 0.05)")
    p.add_argument("--method", default="tm", help="integration method: tm (default), taylor, "
                   "cvode, dop853, tdhcc, tdhes, tdheps")
    p.add_argument("--scheme", help="splitting scheme (default SBAB2C); see 'varint schemes'")
    p.add_argument("--seed", type=int, default=0, help="seed of the random deviation vectors")


def build_parser():
    """The argument parser of the ``varint`` command."""
    parser = _Parser(prog="varint", description=__doc__,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
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
    p.add_argument("indicator", choices=INDICATORS, help="what to compute")
    _add_model_arguments(p)
    _add_state_arguments(p)
    _add_run_options(p)
    p.add_argument("--k", help="lyapunov: number of exponents; gali: orders, e.g. 2,3,4")
    p.add_argument("--t-out", type=int, default=None, help="number of output times (default: "
                   "log-spaced, 10 per decade)")
    p.add_argument("--csv", metavar="FILE", help="write every output to FILE")
    p.add_argument("--png", metavar="FILE", help="plot to FILE")
    p.set_defaults(handler=_cmd_run)

    p = sub.add_parser("map", help="a chaos map of a grid on a surface of section",
                       description="Evaluate an indicator (final SALI, GALI_k, X1, MEGNO, FLI or "
                       "OFLI) on a grid "
                       "of a surface of section q[plane] = 0 at fixed energy, with p[plane] >= "
                       "0 solved from it, locally on all cores or on a Dask cluster.")
    _add_model_arguments(p, orbit=False)
    p.add_argument("--energy", type=float, help="energy of the section (required)")
    p.add_argument("--plane", type=int, default=0, help="coordinate index of the section "
                   "(default 0: x = 0)")
    p.add_argument("--axes", help="state indices of the grid axes (default: the next coordinate "
                   "and its momentum, 1,3 = y,py for 2 dof)")
    p.add_argument("--u", default="-0.45:0.7:100", help="first axis START:STOP:NUM "
                   "(default -0.45:0.7:100; write --u=-0.4:0.6:50 when START is negative)")
    p.add_argument("--v", default="-0.45:0.45:100", help="second axis START:STOP:NUM "
                   "(default -0.45:0.45:100)")
    p.add_argument("--indicator", default="sali", help="sali (default), gali, gali_K, x1, "
                   "megno, fli, ofli")
    _add_run_options(p, t_end=1e3)
    p.add_argument("--threshold", help="early-stopping threshold, or 'none' (default: the "
                   "indicator's, 1e-8 for SALI)")
    p.add_argument("--chunk-size", type=int, default=None, help="orbits per chunk")
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
    p.add_argument("--target", type=float, required=True, help="largest acceptable error")
    p.add_argument("--metric", default="energy", choices=("energy", "tangent", "X1"),
                   help="what the error measures (default energy)")
    p.add_argument("--t-end", type=float, default=1e4, help="horizon of the job (default 1e4)")
    p.add_argument("--pilot-t", type=float, default=None, help="pilot horizon (default "
                   "min(t_end, 100))")
    p.add_argument("--csv", metavar="FILE", help="write the table to FILE")
    p.set_defaults(handler=_cmd_select)

    p = sub.add_parser("study", help="run a study of studies/ (paper reproduction, "
                       "benchmarks)", description="Run studies/NAME.py from the source tree; "
                       "arguments after NAME go to the study (e.g. --quick).")
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
    return parser


def main(argv=None):
    """Entry point of the ``varint`` console script; returns the exit status."""
    from .driver import IntegrationError

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        args.handler(args)
    except BrokenPipeError:  # e.g. piped into head: not an error of the command
        sys.stderr.close()
        return 0
    except IntegrationError as exc:
        print(f"varint {args.command}: run failed: {_one_line(exc)}", file=sys.stderr)
        return 1
    except (ValueError, ImportError, OSError) as exc:
        print(f"varint {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    return 0


def _one_line(exc):
    return " ".join(str(exc).split())


if __name__ == "__main__":
    sys.exit(main())
