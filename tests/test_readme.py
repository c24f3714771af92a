"""Every ```python block of README.md runs alone (in a fresh namespace, in a
temporary directory, as a reader pastes it), so the README cannot drift
from the code and no block leans on names an earlier one defined.

Blocks whose horizons or grids would take minutes run with the reductions
of REDUCED; the README says so beside each of them. Every reduction must
apply, so a README edit that drops its target fails here instead of
silently running the long version. Doctest-style lines (">>> ", "... ")
run as code. The Dask block (a local cluster) is slow; its quick
counterpart is the same map run here without the cluster."""

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
    ('grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.7, 200),\n'
     '                           np.linspace(-0.45, 0.45, 200))',
     'grid = varint.section_grid(model, 0.125, np.linspace(-0.45, 0.7, 20),\n'
     '                           np.linspace(-0.45, 0.45, 20))'),
    ('r = varint.lyapunov_spectrum(model, x0, 1000.0, tau=0.05, method=method, **options)',
     'r = varint.lyapunov_spectrum(model, x0, 50.0, tau=0.05, method=method, **options)'),
    ('d = varint.departure(model, x0, "tdhcc", tau=0.05, t_end=2e4)',
     'd = varint.departure(model, x0, "tdhcc", tau=0.05, t_end=2e3)'),
    # The lattice block: the same calls on shorter times and fewer realisations.
    ('"dvd", 1e4, 0.2, scheme="ABA864")', '"dvd", 20.0, 0.2, scheme="ABA864")'),
    ('"spreading", 1e3, 0.1, scheme="s9ABC6")', '"spreading", 5.0, 0.1, scheme="s9ABC6")'),
    ('varint.ensemble(DDNLS, range(1, 21),', 'varint.ensemble(DDNLS, range(1, 3),'),
    ('"dvd", 1e5, 0.2, params={"shape": 512,', '"dvd", 100.0, 0.2, params={"shape": 64,'),
    ('e.exponent("x1", (1e3, 1e5))', 'e.exponent("x1", (10.0, 100.0))'),
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


def _run_block(i, tmp_path, monkeypatch):
    """README block ``i`` (reduced) alone; its namespace."""
    monkeypatch.chdir(tmp_path)
    block, used = reduced(BLOCKS[i])
    namespace = {"__name__": "readme"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            exec(compile(block, f"README.md python block {i + 1}", "exec"), namespace)
        except Exception as exc:  # say which block, then fail
            pytest.fail(f"README python block {i + 1} failed alone: {type(exc).__name__}: "
                        f"{exc}\n{block}")
    return namespace, used


BLOCKS = blocks(README.read_text())
#: Blocks that start a Dask cluster.
DASK = [i for i, b in enumerate(BLOCKS) if "dask" in b]


def test_the_blocks_are_found_and_every_reduction_applies():
    assert len(BLOCKS) >= 10 and len(DASK) == 1
    applied = set()
    for block in BLOCKS:
        applied |= reduced(block)[1]
    missing = [REDUCED[i][0] for i in range(len(REDUCED)) if i not in applied]
    assert not missing, f"README no longer contains these reduced lines: {missing}"


@pytest.mark.parametrize("i", [i for i in range(len(BLOCKS)) if i not in DASK],
                         ids=lambda i: f"block{i + 1}")
def test_every_python_block_of_the_readme_runs_alone(i, tmp_path, monkeypatch):
    namespace, _ = _run_block(i, tmp_path, monkeypatch)
    # What some blocks promise, checked on what they computed.
    if "out" in namespace and hasattr(namespace["out"], "state"):
        assert np.isfinite(namespace["out"].state).all()
    if isinstance(namespace.get("r"), varint.ChaosMapResult):
        assert namespace["r"].values.shape == (len(namespace["grid"]),)


@pytest.mark.slow  # a Dask cluster: about a minute
def test_the_dask_block_runs_alone_and_matches_the_local_map(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    local = next(i for i, b in enumerate(BLOCKS) if 'checkpoint="hh_map")' in b)
    maps = []
    for i in (local, DASK[0]):
        (tmp_path / str(i)).mkdir()
        namespace, _ = _run_block(i, tmp_path / str(i), monkeypatch)
        maps.append(namespace["r"])
        if namespace.get("client") is not None:
            namespace["client"].close()
    # A cluster changes no bit.
    assert maps[0].values.tobytes() == maps[1].values.tobytes()
