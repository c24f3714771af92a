"""Ensembles over disorder: realisations are deterministic and independent
of their order, kept and resumed from a checkpoint directory, and the
averaged exponent reproduces the law of regular motion, Λ ∝ t^{−1}."""

import importlib

import numpy as np
import pytest

import varint
from varint.checkpoint import CheckpointError
from varint.ensemble import ensemble
from varint.models import DDNLS, DisorderedKG

#: The module (varint.ensemble is the function).
ENSEMBLE = importlib.import_module("varint.ensemble")
PARAMS = {"shape": 12, "W": 4.0, "beta": 1.0}
T_OUT = [1.0, 2.0, 4.0]


def block(model, seed):
    return model.initial_block(3, 1.0, seed=seed)


def small(seeds, **kw):
    return ensemble(DDNLS, seeds, block, "dvd", 4.0, 0.1, params=PARAMS, scheme="s9ABC6",
                    t_out=T_OUT, progress=False, **kw)


def test_a_realisation_is_its_own_run_whatever_the_order():
    e = small([3, 5])
    f = small([5])
    model = DDNLS(**PARAMS, seed=5)
    r = varint.run(model, block(model, 5), "dvd", 4.0, 0.1, scheme="s9ABC6", t_out=T_OUT,
                   seed=5)
    for name in ("x1", "m2", "dvd_m2", "participation"):
        assert np.array_equal(e[name][1], f[name][0]), name
        assert np.array_equal(e[name][1], r[name]), name
    assert not np.array_equal(e["m2"][0], e["m2"][1])       # other disorder, other packet
    assert e.status.tolist() == [0, 0] and e.seeds.tolist() == [3, 5]
    assert np.all(np.abs(e.energy_error) < 1e-4)


def test_finished_realisations_are_kept_and_reused(tmp_path):
    first = small([1, 2], checkpoint=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["seed_1.npz", "seed_2.npz"]
    again = small([1, 2, 4], checkpoint=tmp_path)
    assert again.provenance.options["resumed"] == 2
    assert np.array_equal(again["x1"][:2], first["x1"])
    with pytest.raises(CheckpointError, match="other parameters"):
        ensemble(DDNLS, [1], block, "dvd", 4.0, 0.1, params={**PARAMS, "beta": 2.0},
                 scheme="s9ABC6", t_out=T_OUT, checkpoint=tmp_path, progress=False)


def test_stored_realisations_are_checked_without_building_their_runs(tmp_path, monkeypatch):
    # Resuming reads each stored realisation's parameters off its run
    # specification: a run (and its propagator) is built only for the
    # realisations that still have to run.
    small([1, 2], checkpoint=tmp_path)
    built = []
    original = ENSEMBLE.Run

    def counting(spec, *args, **kwargs):
        built.append(spec.seed)
        return original(spec, *args, **kwargs)

    monkeypatch.setattr(ENSEMBLE, "Run", counting)
    again = small([1, 2, 4], checkpoint=tmp_path)
    assert built == [4] and again.provenance.options["resumed"] == 2


def test_an_automatic_step_is_chosen_once_and_each_realisation_is_its_run(monkeypatch):
    # τ left open: the first realisation's pilot chooses it for all (one
    # pilot, one set of output times), and realisation s is then the run of
    # its model at that τ, bit for bit.
    pilots = []
    original = varint.stepsize.choose_step

    def counting(*args, **kwargs):
        pilots.append(args[0])
        return original(*args, **kwargs)

    monkeypatch.setattr(varint.stepsize, "choose_step", counting)
    e = ensemble(DDNLS, [3, 5], block, "dvd", 4.0, params=PARAMS, scheme="s9ABC6",
                 t_out=T_OUT, progress=False)
    assert len(pilots) == 1 and pilots[0].seed == 3
    tau = e.provenance.tau
    assert e.provenance.tau_choice["rule"] != "given" and 0 < tau <= T_OUT[0]
    assert np.allclose(e.t, T_OUT)
    model = DDNLS(**PARAMS, seed=5)
    r = varint.run(model, block(model, 5), "dvd", 4.0, tau, scheme="s9ABC6", t_out=T_OUT,
                   seed=5)
    for name in ("x1", "m2", "dvd_m2"):
        assert np.array_equal(e[name][1], r[name]), name


def test_regular_motion_gives_lambda_proportional_to_inverse_time():
    """Klein–Gordon chains at energy 1e-4 (nearly linear: quasi-periodic
    motion), one site excited: the disorder-averaged ⟨log Λ⟩ falls as
    t^{−1} (Skokos & Gerlach 2010; Senyange et al. 2018). Measured over
    [1e2, 1e4] on three sets of 12 realisations: −1.0014, −1.0010, −1.0004,
    each with a standard error 0.03 (single slopes spread ±0.1)."""
    e = ensemble(DisorderedKG, range(1, 13), lambda m, s: m.initial_block(1, 1e-4, seed=s),
                 "dvd", 1e4, 0.2, params={"shape": 16, "W": 4.0}, scheme="ABA864",
                 t_out=np.geomspace(10, 1e4, 31), progress=False)
    fit = e.exponent("x1", (100, 1e4))
    assert fit["realisations"] == 12
    assert abs(fit["a"] + 1) < 0.1 and 0.03 < fit["a_std"] < 0.3, fit
    assert fit["a_err"] == pytest.approx(fit["a_std"] / np.sqrt(12))
    mean, std, count = e.log_mean("x1")
    assert count.tolist() == [12] * 31 and np.all(std > 0)


@pytest.mark.parametrize("call, match", [
    (lambda: small([1, 1]), "seeds must be distinct"),
    (lambda: small([]), "seeds holds no realisation"),
    (lambda: small([-1]), "seeds must be non-negative integers"),
    (lambda: small([1], seed=3), "seed= is each realisation's own seed"),
    (lambda: ensemble(3, [1], block, "dvd", 1.0), "model must be a model class"),
    (lambda: small([1]).exponent("x1", (1.0, 2.0)), "holds 2 output times"),
])
def test_bad_ensembles_are_refused(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.slow
def test_a_dask_cluster_gives_the_same_bits(tmp_path):
    """Realisations as tasks on a LocalCluster: the values are bitwise
    those of a run in this process, and the realisations finished there
    resume here."""
    import warnings

    distributed = pytest.importorskip("distributed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        client = distributed.Client(cluster)
    try:
        remote = small([1, 2, 3], client=client, checkpoint=tmp_path)
    finally:
        client.close()
        cluster.close()
    local = small([1, 2, 3])
    for name in ("x1", "m2", "dvd_m2"):
        assert np.array_equal(remote[name], local[name]), name
    assert remote.provenance.options["client"] == "dask (2 threads)"
    again = small([1, 2, 3], checkpoint=tmp_path)
    assert again.provenance.options["resumed"] == 3
    assert np.array_equal(again["x1"], local["x1"])
