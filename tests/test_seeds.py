"""varint.seeds: the fast per-orbit streams are NumPy's, bit for bit."""

import numpy as np
import pytest

from varint import seeds
from varint.seeds import standard_normals
from varint.state import initial_deviations


@pytest.fixture(autouse=True)
def compiled_loop_from_the_first_orbit(monkeypatch):
    """Every test below checks the compiled loop, which a process otherwise
    uses only after its first NUMPY_FIRST orbits."""
    monkeypatch.setattr(seeds, "NUMPY_FIRST", 0)


@pytest.mark.parametrize("seed", [0, 1, 7, 20100927, 2 ** 31, 2 ** 32 - 1, 2 ** 32, 2 ** 70])
def test_standard_normals_are_default_rng_per_orbit(seed):
    # Small and large indices, and ones beyond uint32 (NumPy's own path).
    indices = [0, 1, 2, 5, 999, 123456, 2 ** 32 - 1, 2 ** 32, 2 ** 40 + 3]
    got = standard_normals(seed, indices, (6, 3))
    want = np.array([np.random.default_rng([seed, i]).standard_normal((6, 3))
                     for i in indices])
    assert got.tobytes() == want.tobytes()


def test_many_orbits_and_shapes():
    idx = np.random.default_rng(1).permutation(5000)[:700]
    for shape in [(4, 1), (4, 2), (2, 4), (128, 1), ()]:
        got = standard_normals(3, idx, shape)
        want = np.array([np.random.default_rng([3, int(i)]).standard_normal(shape)
                         for i in idx])
        assert got.shape == (700,) + shape and got.tobytes() == want.tobytes()


def test_no_orbits():
    assert standard_normals(0, [], (4, 2)).shape == (0, 4, 2)


def test_initial_deviations_do_not_depend_on_the_batch():
    # Orbit 37's vectors are the same alone and inside a permuted batch.
    idx = np.random.default_rng(5).permutation(100)
    batch = initial_deviations(4, 2, 100, 11, idx)
    alone = initial_deviations(4, 2, 1, 11, [37])
    assert batch[np.flatnonzero(idx == 37)[0]].tobytes() == alone[0].tobytes()
    # Orthonormal columns.
    gram = np.einsum("mik,mil->mkl", batch, batch)
    assert np.abs(gram - np.eye(2)).max() < 1e-14


def test_a_numpy_that_seeds_otherwise_falls_back_to_its_own_path(monkeypatch):
    # A fast path that no longer matches NumPy (here: a wrong PCG64
    # multiplier) is caught by the once-per-process check.
    monkeypatch.setattr(seeds, "_PCG_MULT", seeds._PCG_MULT + 2)
    seeds._fast_path_is_numpys.cache_clear()
    try:
        assert not seeds._fast_path_is_numpys()
        got = standard_normals(5, [3, 4], (4, 2))
        want = np.array([np.random.default_rng([5, i]).standard_normal((4, 2)) for i in (3, 4)])
        assert got.tobytes() == want.tobytes()
    finally:
        seeds._fast_path_is_numpys.cache_clear()


def test_every_branch_of_the_ziggurat_is_numpys():
    # 300 000 draws: ~2000 leave the ziggurat's rectangles (its wedges) and
    # ~70 fall in its tail beyond r = 3.654 (the exponential pairs).
    idx = np.arange(300)
    got = standard_normals(5, idx, (1000,))
    want = np.array([np.random.default_rng([5, int(i)]).standard_normal(1000) for i in idx])
    assert got.tobytes() == want.tobytes()
    assert (np.abs(got) > 3.654152885361009).sum() > 20


def test_a_process_draws_its_first_orbits_with_numpy_then_compiled(monkeypatch):
    # The compiled loop (loaded and checked against NumPy at its first use)
    # is not consulted for the first NUMPY_FIRST orbits, then it is.
    asked = []
    fast = seeds._fast_path_is_numpys
    monkeypatch.setattr(seeds, "_fast_path_is_numpys", lambda: asked.append(1) or fast())
    monkeypatch.setattr(seeds, "NUMPY_FIRST", 8)
    monkeypatch.setattr(seeds, "_numpy_drawn", 0)
    for indices in ([0], [1, 2, 3, 4, 5], [6, 7], [8], [9, 10]):
        got = standard_normals(3, indices, (4, 2))
        want = np.array([np.random.default_rng([3, i]).standard_normal((4, 2))
                         for i in indices])
        assert got.tobytes() == want.tobytes()
    assert len(asked) == 2          # [8] and [9, 10]: after 8 orbits
