"""Every ```python block of README.md runs, in order and in one namespace
(later blocks use what earlier ones defined), in a temporary directory, so
the README cannot drift from the code.

Blocks whose horizons or grids would take minutes run with the reductions
of REDUCED; the README says so beside each of them. Every reduction must
apply, so a README edit that drops its target fails here instead of
silently running the long version. Doctest-style lines (">>> ", "... ")
run as code."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import varint

README = Path(__file__).resolve().parent.parent / "README.md"

#: (text in the README, what the test runs instead).
REDUCED = [
    ('r = varint.lyapunov_spectrum(model, x0, t_end=1e5, tau=0.05, scheme="SBAB2C")',
     'r = varint.lyapunov_spectrum(model, x0, t_end=1e3, tau=0.05, scheme="SBAB2C")'),
    ('g = varint.gali(model, x0, 1e5, tau=0.05, k=(2, 3, 4))',
     'g = varint.gali(model, x0, 1e3, tau=0.05, k=(2, 3, 4))'),
    ('s = varint.sali(model, x0, 1e4)', 's = varint.sali(model, x0, 500.0)'),
    ('m = varint.megno(model, x0, 1e4)', 'm = varint.megno(model, x0, 500.0)'),
    ('np.linspace(-0.45, 0.7, 200),    # y', 'np.linspace(-0.45, 0.7, 20),    # y'),
    ('np.linspace(-0.45, 0.45, 200))   # p_y', 'np.linspace(-0.45, 0.45, 20))   # p_y'),
    ('r = varint.chaos_map(model, grid, "sali", t_end=1e3, tau=0.05, checkpoint="hh_map")',
     'r = varint.chaos_map(model, grid, "sali", t_end=100.0, tau=0.05, checkpoint="hh_map")'),
    ('client = Client("tcp://scheduler:8786")',
     'client = Client(LocalCluster(n_workers=1, threads_per_worker=1, processes=False, '
     'dashboard_address=None))'),
    ('from dask.distributed import Client\n', 'from dask.distributed import Client, LocalCluster\n'),
    # The same map as the local one above: a cluster changes no bit.
    ('t_end=1e4, client=client, checkpoint="hh_map_dask")',
     't_end=100.0, tau=0.05, client=client, checkpoint="hh_map_dask")'),
    ('r = varint.lyapunov_spectrum(model, x0, 1000.0, tau=0.05, method=method, **options)',
     'r = varint.lyapunov_spectrum(model, x0, 50.0, tau=0.05, method=method, **options)'),
    ('d = varint.departure(model, x0, "tdhcc", tau=0.05, t_end=2e4)',
     'd = varint.departure(model, x0, "tdhcc", tau=0.05, t_end=2e3)'),
]


def blocks(text):
    """The ```python blocks of ``text``, with doctest prompts removed."""
    out = []
    for block in re.findall(r"```python\n(.*?)```", text, re.S):
        lines = [re.sub(r"^(>>>|\.\.\.) ?", "", line) for line in block.splitlines()]
        out.append("\n".join(lines) + "\n")
    return out


def reduced(code):
    used = set()
    for i, (old, new) in enumerate(REDUCED):
        if old in code:
            code = code.replace(old, new)
            used.add(i)
    return code, used


@pytest.mark.slow  # a Dask cluster and a dozen runs: about a minute
def test_every_python_block_of_the_readme_runs(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("VARINT_CACHE_DIR", str(tmp_path / "cache"))
    code = blocks(README.read_text())
    assert len(code) >= 6
    namespace = {"__name__": "readme"}
    applied, maps = set(), []
    try:
        for i, block in enumerate(code):
            block, used = reduced(block)
            applied |= used
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)
                try:
                    exec(compile(block, f"README.md python block {i + 1}", "exec"), namespace)
                except Exception as exc:  # say which block, then fail
                    pytest.fail(f"README python block {i + 1} failed: {type(exc).__name__}: "
                                f"{exc}\n{block}")
            # Later blocks reuse the name r: keep each map as it is made.
            if isinstance(namespace.get("r"), varint.ChaosMapResult) and (
                    not maps or namespace["r"] is not maps[-1]):
                maps.append(namespace["r"])
    finally:
        client = namespace.get("client")
        if client is not None:
            client.close()
    missing = [REDUCED[i][0] for i in range(len(REDUCED)) if i not in applied]
    assert not missing, f"README no longer contains these reduced lines: {missing}"
    # What the blocks promise, checked on what they computed.
    assert len(maps) == 2  # the local map and the Dask map, bitwise equal
    for r in maps:
        assert r.values.shape == (len(namespace["grid"]),)
    assert maps[0].values.tobytes() == maps[1].values.tobytes()
    assert np.isfinite(namespace["out"].state).all()
