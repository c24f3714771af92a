"""``import varint`` imports no heavy library; a public name asked for
imports the submodule that defines it, and the functions keep the names
their submodules share (issue 28, "imports on demand")."""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import varint

ROOT = Path(__file__).resolve().parent.parent


def fresh(code):
    """Run ``code`` in a new interpreter on this source tree; its JSON."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                          capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_import_loads_no_heavy_library():
    heavy = ("sympy", "scipy", "numba", "matplotlib", "pandas", "xarray", "dask", "heyoka")
    loaded = fresh("import sys, json, varint; "
                   f"print(json.dumps([m for m in {heavy!r} if m in sys.modules]))")
    assert loaded == []


def test_a_public_name_loads_its_own_submodule_only():
    """The first name asked for imports its submodule (and numba with it),
    not the rest of the API; every other name is imported when asked for,
    and is what its submodule defines."""
    others = ("maps", "ensemble", "sections", "grids", "departure", "selection", "prepared",
              "element_grid")
    names = fresh("import sys, json, importlib, varint; varint.paper_orbit; "
                  "loaded = ['numba' in sys.modules, 'paper_orbit' in vars(varint), "
                  f"[m for m in {others!r} if 'varint.' + m in sys.modules], "
                  "'chaos_map' in vars(varint)]; "
                  "wrong = [n for n in varint.__all__ if n != 'models' and getattr(varint, n) "
                  "is not getattr(importlib.import_module('varint.' + varint._EXPORTS[n]), n)]; "
                  "print(json.dumps([*loaded, wrong, "
                  "sorted(n for n in varint.__all__ if n not in vars(varint))]))")
    assert names == [True, True, [], False, [], []]


def test_functions_keep_the_names_of_their_submodules():
    # A submodule imported before the package's names were asked for (by
    # another submodule) must not take the name of its function.
    kinds = fresh("import json, varint.sections, varint; "
                  "print(json.dumps([callable(varint.run), callable(varint.departure), "
                  "callable(varint.ensemble), callable(varint.element_grid), "
                  "type(varint.models).__name__]))")
    assert kinds == [True, True, True, True, "module"]


def test_unknown_name_is_an_attribute_error():
    try:
        varint.no_such_name  # noqa: B018
    except AttributeError as exc:
        assert "no_such_name" in str(exc)
    else:
        raise AssertionError("varint.no_such_name did not raise")
    assert set(varint.__all__) <= set(dir(varint))


def test_type_checkers_see_every_lazy_name_from_its_module():
    """The ``TYPE_CHECKING`` imports of varint/__init__.py (what mypy sees)
    name exactly the lazy exports, each from the submodule that defines it."""
    tree = ast.parse((ROOT / "varint" / "__init__.py").read_text())
    block = next(node for node in tree.body if isinstance(node, ast.If)
                 and getattr(node.test, "id", "") == "_TYPE_CHECKING")
    seen = {}
    for node in block.body:
        for alias in node.names:
            seen[alias.name] = node.module or alias.name
    assert seen == varint._EXPORTS


def test_a_process_on_cached_kernels_imports_no_sympy_and_compiles_nothing():
    """Once a process has compiled them, a fresh process runs R1's spectrum
    and a FLI map of 256 orbits run in parallel over blocks of SIMD lanes
    without importing SymPy or Dask's distributed (a map on this machine
    asks no Dask worker) and without compiling anything: the generated
    steppers (the lanes' kernel that the threads run included) come from
    the cache. In a cold cache R1's short run takes the compact stepper,
    whose module has no lanes: only the modules with lanes count the lanes
    kernel's cache hits (the test passed only after another had cached
    R1's written-out stepper)."""
    code = ("import sys, json, numpy as np, varint; from varint import compiling; "
            "m, x = varint.paper_orbit('R1'); "
            "varint.lyapunov_spectrum(m, x, t_end=10.0, tau=0.05, progress=False); "
            "hh = varint.models.HenonHeiles(); "
            "grid = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.65, 16), "
            "np.linspace(-0.45, 0.45, 16)); "
            "varint.chaos_map(hh, grid, 'fli', t_end=10.0, progress=False, parallel=True); "
            "hits = sum(sum(mod.blocks_serial.stats.cache_hits.values()) "
            "for name, mod in list(sys.modules.items()) "
            "if name.startswith('varint_stepper_') and hasattr(mod, 'blocks_serial')); "
            "heavy = [m for m in ('sympy', 'distributed') if m in sys.modules]; "
            "print(json.dumps([heavy, compiling.compile_seconds(), hits]))")
    fresh(code)                             # compiles what the cache lacks
    heavy, compiled, lanes_hits = fresh(code)
    assert heavy == []
    assert compiled == 0.0
    assert lanes_hits >= 1


def test_a_default_fli_map_that_keeps_constant_steps_imports_no_sympy():
    """A FLI map with every default weighs the logarithmic Hamiltonian
    (``maps._log_candidate``). On Hénon–Heiles U = C − V spans less than
    ``U_SPREAD_MIN`` even counted as for a kinetic A, so the map keeps its
    constant step without reading the model's form through SymPy (which it
    loaded before: ~0.35 s of a first map)."""
    code = ("import sys, json, numpy as np, varint; "
            "hh = varint.models.HenonHeiles(); "
            "grid = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.65, 8), "
            "np.linspace(-0.45, 0.45, 8)); "
            "r = varint.chaos_map(hh, grid, 'fli', t_end=10.0, progress=False); "
            "print(json.dumps(['sympy' in sys.modules, r.provenance.method]))")
    loaded, method = fresh(code)
    assert method == "tm"
    assert loaded is False


def test_version_and_metadata_on_demand():
    """``import varint`` reads no file for its version and imports no
    importlib.metadata (~15 ms); ``__version__`` is worked out when asked."""
    got = fresh("import sys, json; before = 'importlib.metadata' in sys.modules; "
                "import varint; after = 'importlib.metadata' in sys.modules; "
                "print(json.dumps([before or not after, '__version__' in vars(varint), "
                "varint.__version__, '__version__' in dir(varint)]))")
    assert got == [True, False, varint.__version__, True]
    text = (ROOT / "pyproject.toml").read_text()
    assert f'\nversion = "{varint.__version__}"' in text


def test_a_run_of_one_model_imports_no_other_models_kernels():
    """The paper's R1 spectrum imports neither the lattices, stencils,
    planetary systems nor symplectic maps (a hundred kernels), nor the
    parts of the API it does not call (chaos maps, ensembles, sections,
    grids: issue 28, ≈ 14 ms of CPU of a first run; the checkpoint file
    format of a run given no checkpoint file), and every
    lazy name of varint.models comes from the submodule that defines it."""
    code = ("import sys, json, varint; m, x = varint.paper_orbit('R1'); "
            "varint.lyapunov_spectrum(m, x, t_end=1.0, tau=0.05, progress=False); "
            "mods = ('lattice', 'stencil', 'kg', 'fput', 'fpu', 'ddnls', 'planetary', 'maps', "
            "'symbolic'); api = ('maps', 'ensemble', 'sections', 'grids', 'departure', "
            "'selection', 'prepared', 'element_grid', 'checkpoint'); "
            "print(json.dumps([[m for m in mods if 'varint.models.' + m in sys.modules], "
            "[m for m in api if 'varint.' + m in sys.modules]]))")
    assert fresh(code) == [[], []]
    for name, module in varint.models._LAZY.items():
        assert getattr(varint.models, name).__module__ == f"varint.models.{module}", name
    assert set(varint.models.__all__) <= set(dir(varint.models))


def test_a_run_imports_the_indicator_it_computes_and_no_other():
    """A first Lyapunov run in a new process imports the Lyapunov
    indicator's module only; asking for another name, or listing the
    registry, imports the others (issue 28, a first run's start-up)."""
    modules = ("lyapunov", "alignment", "megno", "local_exponents", "orbit", "lattice")
    loaded = fresh("import sys, json, varint; "
                   "m, x = varint.paper_orbit('R1'); "
                   "varint.lyapunov_spectrum(m, x, t_end=0.5, tau=0.05, progress=False); "
                   f"seen = lambda: [m for m in {modules!r} if 'varint.indicators.' + m "
                   "in sys.modules]; "
                   "first = seen(); varint.get_indicator('GALI_3'); second = seen(); "
                   "names = sorted(varint.INDICATORS); "
                   "print(json.dumps([first, second, seen(), names]))")
    assert loaded[:3] == [["lyapunov"], ["lyapunov", "alignment"], list(modules)]
    assert loaded[3] == sorted(["lyapunov", "gali", "sali", "megno", "fli", "ofli",
                                "local_exponents", "integrate", "spreading", "dvd"])


def test_a_first_run_loads_no_derivative_kernel_for_its_input_check():
    """The bad-input check of a first R1 run (∇V, D²V and the third
    derivatives finite at the initial state) runs the built-in kernels'
    Python source, so a new process loads none of the three compiled
    kernels from numba's cache (issue 28: ~10 ms of CPU) — its generated
    stepper computes them itself; the check still refuses a state where
    they overflow, with the compiled check's words."""
    code = ("import json, varint; m, x = varint.paper_orbit('R1'); "
            "varint.lyapunov_spectrum(m, x, t_end=1.0, tau=0.05, progress=False); "
            "kernels = (m.grad_kernel, m.hess_kernel, m.third_kernel); "
            "loaded = [len(k.overloads) for k in kernels]; "
            "x[0] = 1e200\n"
            "try:\n"
            "    varint.lyapunov_spectrum(m, x, t_end=1.0, tau=0.05, progress=False)\n"
            "except ValueError as exc:\n"
            "    error = str(exc)\n"
            "print(json.dumps([loaded, error, [len(k.overloads) > 0 for k in kernels]]))")
    loaded, error, after = fresh(code)
    assert loaded == [0, 0, 0]
    assert "the derivatives of V (HenonHeiles) are not finite at the initial state, " \
           "q = [1e+200, " in error and "the gradient ∇V is [" in error
    assert after == [True, True, True]      # named by the compiled kernels


def test_a_first_run_with_a_cache_dir_set_reads_no_package_metadata(monkeypatch):
    """With ``$VARINT_CACHE_DIR`` set, a first R1 run neither imports
    ``platformdirs`` (it only names the default directory) nor asks
    :func:`importlib.metadata.version` (SymPy's version is read from its
    ``release.py``: a metadata look-up scans every installed distribution)."""
    from varint import cachedir

    monkeypatch.setenv("VARINT_CACHE_DIR", str(cachedir.location()))
    code = ("import sys, json, importlib.metadata as md; asked = []; "
            "real = md.version; "
            "md.version = lambda name: asked.append(name) or real(name); "
            "import varint; "
            "m, x = varint.paper_orbit('R1'); "
            "varint.lyapunov_spectrum(m, x, t_end=1.0, tau=0.05, progress=False); "
            "print(json.dumps(['platformdirs' in sys.modules, asked]))")
    assert fresh(code) == [False, []]


def test_the_generator_identity_follows_sympys_version_and_the_sources(tmp_path, monkeypatch):
    """A changed SymPy release or a changed generator source changes the
    generator identity (numba's cache does not follow dependencies)."""
    from varint.codegen import stepper

    release = tmp_path / "release.py"
    release.write_bytes(stepper._sympy_release().read_bytes())
    source = tmp_path / "layer.py"
    source.write_text("X = 1\n")
    monkeypatch.setattr(stepper, "_sympy_release", lambda: release)
    monkeypatch.setattr(stepper, "generator_sources", lambda: [source])

    def identity():
        stepper._generator_id.cache_clear()
        return stepper._generator_id()

    try:
        base = identity()
        assert identity() == base
        release.write_text(release.read_text() + "__version__ = '0.0.0-other'\n")
        bumped = identity()
        assert bumped != base
        source.write_text("X = 2\n")
        assert identity() not in (base, bumped)
    finally:
        stepper._generator_id.cache_clear()
