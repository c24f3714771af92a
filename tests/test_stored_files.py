"""Files read back — run checkpoints, chaos-map chunks, ensemble
realisations, saved results — are tied to the call that made them and
validated before any use. A checksum only catches accidents (anyone can
edit a file and compute a new one), so each case here edits a file *and*
makes its checksum right again: the outcome must be a clean error naming
the file and the field, or a recomputation with a warning — never an
interpreter abort, NaN, or another call's values."""

import io
import json
import time
import zipfile

import numpy as np
import pytest

import varint
from varint import checkpoint as ckpt
from varint import maps as cm
from varint import store as st
from varint.checkpoint import CheckpointError
from varint.models import DDNLS, HenonHeiles
from tests.helpers import assert_bitwise_equal, hook_advance

T_END = 100.0


class Stop(Exception):
    pass


def stop():
    raise Stop


@pytest.fixture(scope="module")
def c1():
    return varint.paper_orbit("C1")


@pytest.fixture(scope="module")
def full(c1):
    return varint.lyapunov_spectrum(*c1, T_END)


@pytest.fixture
def partial(c1, tmp_path, monkeypatch):
    """A checkpoint of C1's spectrum, stopped after its third chunk."""
    path = tmp_path / "run.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", 3, stop)
        with pytest.raises(Stop):
            varint.lyapunov_spectrum(*c1, T_END, checkpoint=path, checkpoint_interval=0)
    return path


def rewrite(path, edit):
    """Read the checkpoint, ``edit(snapshot)`` it, write it back with a
    valid trailer (as someone who edits a file would)."""
    snap = ckpt.read(path)
    edit(snap)
    ckpt.write(path, snap)


def _set(name, value):
    def edit(snap):
        setattr(snap.state, name, value(getattr(snap.state, name)))
    return edit


EDITS = {
    # The original fault: a wrong shape aborted the interpreter.
    "x of another shape": (_set("x", lambda x: np.vstack([x, x])), "x"),
    "x as float32": (_set("x", lambda x: x.astype(np.float32)), "x"),
    "W with another k": (_set("W", lambda W: W[:, :, :2].copy()), "W"),
    "W of another dimension": (_set("W", lambda W: W[:, :2, :].copy()), "W"),
    "x NaN": (_set("x", lambda x: np.full_like(x, np.nan)), "x"),
    "W infinite": (_set("W", lambda W: W * np.inf), "W"),
    # NaN and -inf exponents resumed as "accurate".
    "acc_m zero": (_set("acc_m", lambda a: np.zeros_like(a)), "acc_m"),
    "acc_m negative": (_set("acc_m", lambda a: -a), "acc_m"),
    "acc_m NaN": (_set("acc_m", lambda a: a * np.nan), "acc_m"),
    "acc_e off the 2^500 grid": (_set("acc_e", lambda a: a + 7), "acc_e"),
    "acc_e as float": (_set("acc_e", lambda a: a.astype(float)), "acc_e"),
    "dependent vectors": (_set("W", lambda W: np.repeat(W[:, :, :1], W.shape[2], axis=2)), "W"),
    "status unknown": (_set("status", lambda s: s + 42), "status"),
    "status failed, no step": (_set("status", lambda s: s + 1), "fail_step"),
    "fail_step for a running orbit": (_set("fail_step", lambda f: f + 5), "fail_step"),
    "step beyond the end": (_set("step", lambda s: 10 ** 9), "step"),
    "step negative": (_set("step", lambda s: -3), "step"),
    "step a boolean": (_set("step", lambda s: True), "step"),
    "step behind the records": (_set("step", lambda s: 1), "step"),
    "counts negative": (_set("counts", lambda c: {**c, "steps": -1}), "counts"),
    "extra of another length": (_set("extra", lambda e: {**e, "junk": np.zeros(7)}), "extra.junk"),
}


@pytest.mark.parametrize("case", sorted(EDITS))
def test_an_edited_and_resigned_checkpoint_is_refused_naming_the_field(case, c1, partial):
    edit, field = EDITS[case]
    rewrite(partial, edit)
    with pytest.raises(CheckpointError) as err:
        varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial)
    message = str(err.value)
    assert str(partial) in message and field in message, message
    assert len(message.splitlines()) == 1


def _records(edit):
    def apply(snap):
        stacked = snap.records.stacked()
        n = len(snap.records)
        stacked, n = edit(stacked, n)
        snap.records = ckpt.Records.from_stacked(stacked, n)
    return apply


RECORD_EDITS = {
    "exponents NaN": (_records(lambda r, n: ({**r, "exponents": r["exponents"] * np.nan}, n)),
                      "records.exponents"),
    "energy error infinite": (_records(
        lambda r, n: ({**r, "energy_error": r["energy_error"] + np.inf}, n)),
        "records.energy_error"),
    "a record of another indicator": (_records(lambda r, n: ({**r, "sali": r["energy_error"]},
                                                             n)), "records.sali"),
    "a record missing": (_records(lambda r, n: ({"exponents": r["exponents"]}, n)),
                         "records.energy_error"),
    "exponents of another width": (_records(
        lambda r, n: ({**r, "exponents": r["exponents"][..., :2]}, n)), "records.exponents"),
}


@pytest.mark.parametrize("case", sorted(RECORD_EDITS))
def test_edited_records_are_refused(case, c1, partial):
    edit, field = RECORD_EDITS[case]
    rewrite(partial, edit)
    with pytest.raises(CheckpointError, match=field.replace(".", r"\.")):
        varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial)


def test_an_accumulator_removed_from_a_checkpoint_is_refused(c1, tmp_path, monkeypatch):
    """A MEGNO run's accumulator is part of its state: a checkpoint without
    it (or with one of another shape) is refused, not restarted from zero."""
    path = tmp_path / "megno.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", 2, stop)
        with pytest.raises(Stop):
            varint.megno(*c1, T_END, checkpoint=path, checkpoint_interval=0)
    key = next(k for k, v in ckpt.read(path).state.extra.items() if v.ndim == 3)
    rewrite(path, _set("extra", lambda e: {k: v for k, v in e.items() if k != key}))
    with pytest.raises(CheckpointError, match=f"extra.{key}: missing"):
        varint.megno(*c1, T_END, checkpoint=path)
    rewrite(path, _set("extra", lambda e: {**e, key: np.zeros((1, 1, 2))}))
    with pytest.raises(CheckpointError, match=f"extra.{key}"):
        varint.megno(*c1, T_END, checkpoint=path)


def test_two_stored_outputs_are_not_returned_as_a_finished_run(c1, partial, full):
    """n_records raised to the run's length while only a few are stored:
    refused (it returned 2 outputs as a finished run)."""
    data = partial.read_bytes()
    snap = ckpt.read(partial)
    arrays, meta = ckpt._arrays_and_meta(snap)
    meta["n_records"] = len(full.t)
    _write_raw(partial, arrays, meta)
    with pytest.raises(CheckpointError, match="hold .* outputs, not"):
        varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial)
    partial.write_bytes(data)
    assert_bitwise_equal(varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial), full)


def _write_raw(path, arrays, meta, compression=zipfile.ZIP_STORED):
    """A checkpoint with any arrays and meta, and a valid trailer."""
    import hashlib

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=compression) as zf:
        for name, a in {**arrays, "__meta__": np.array(json.dumps(meta))}.items():
            with zf.open(f"{name}.npy", "w") as member:
                np.lib.format.write_array(member, np.asanyarray(a), allow_pickle=False)
    body = ckpt.MAGIC + buf.getvalue()
    trailer = b"size=%020d sha256=%s\n" % (len(buf.getvalue()),
                                           hashlib.sha256(body).hexdigest().encode())
    path.write_bytes(body + trailer)


@pytest.mark.parametrize("case", ["compressed member", "meta not an object", "step as text",
                                  "wall time negative", "array not listed", "array missing",
                                  "object array"])
def test_a_malformed_checkpoint_archive_is_refused(case, c1, partial):
    snap = ckpt.read(partial)
    arrays, meta = ckpt._arrays_and_meta(snap)
    compression = zipfile.ZIP_STORED
    if case == "compressed member":
        compression = zipfile.ZIP_DEFLATED   # a zip bomb would be one
    elif case == "meta not an object":
        meta = [meta]
    elif case == "step as text":
        meta["step"] = "12"
    elif case == "wall time negative":
        meta["wall_time"] = -1.0
    elif case == "array not listed":
        arrays["state__junk"] = np.zeros(3)
    elif case == "array missing":
        del arrays["state__acc_m"]
    if case == "object array":
        import hashlib

        buf = io.BytesIO()
        np.savez(buf, __meta__=np.array(json.dumps(meta)), x=np.array([object()]))
        body = ckpt.MAGIC + buf.getvalue()
        partial.write_bytes(body + b"size=%020d sha256=%s\n" % (
            len(buf.getvalue()), hashlib.sha256(body).hexdigest().encode()))
    else:
        _write_raw(partial, arrays, meta, compression)
    with pytest.raises(CheckpointError, match="cannot be decoded") as err:
        varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial)
    assert str(partial) in str(err.value)


def test_a_resumed_run_reports_the_cpu_time_it_measured(c1, partial, monkeypatch, full):
    """The CPU time of each session is measured and summed in the
    checkpoint: a resumed run reports the total, and one resumed from a
    checkpoint that did not record it reports None, never an estimate."""
    first = ckpt.read(partial).cpu_time
    assert first > 0
    clock = iter(range(10 ** 6))
    monkeypatch.setattr(time, "process_time", lambda: 5.0 * next(clock))
    r = varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial)
    assert r.provenance.cpu_time > first and r.provenance.cpu_time % 5.0 == pytest.approx(
        first % 5.0)
    monkeypatch.undo()
    assert r.provenance.cpu_time is not None and full.provenance.cpu_time > 0
    # A checkpoint from before CPU time was kept.
    snap = ckpt.read(partial)
    snap.cpu_time = None
    ckpt.write(partial, snap)
    assert varint.lyapunov_spectrum(*c1, T_END, checkpoint=partial).provenance.cpu_time is None


def test_writers_never_delete_a_live_writers_temporary_file(tmp_path, c1):
    """Two processes on one checkpoint: one removed the other's temporary
    file as stale and the other died with 'No such file or directory'.
    Temporary files are named after their writer: a live one's are kept,
    a dead one's removed; a vanished one is said to be."""
    from varint.files import atomic_file, temporary_owner

    path = tmp_path / "run.ckpt"
    with atomic_file(path) as f:
        f.write(b"x")
        (live,) = [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
        owner = temporary_owner(live, path)
        assert owner.alive() and owner.pid == __import__("os").getpid()
        dead = tmp_path / live.name.replace(f".{owner.pid}.", ".999999999.")
        dead.write_bytes(b"")
        assert list(ckpt.stale_temporaries(path)) == [str(dead)]
        varint.lyapunov_spectrum(*c1, 1.0, checkpoint=path)   # begins: removes the dead one
        assert live.exists() and not dead.exists()
    with pytest.raises(OSError, match="deleted by another process"), atomic_file(path) as f:
        for p in tmp_path.glob(".run.ckpt.*.tmp"):
            p.unlink()


# -- chaos-map chunks ------------------------------------------------------------

GRID_U, GRID_V = np.linspace(-0.4, 0.6, 6), np.linspace(-0.4, 0.4, 5)


def hh_map(energy, path=None, **kw):
    hh = HenonHeiles()
    grid = varint.section_grid(hh, energy, GRID_U, GRID_V)
    return varint.chaos_map(hh, grid, "sali", t_end=20.0, tau=0.05, chunk_size=4,
                            checkpoint=path, progress=False, **kw)


@pytest.fixture(scope="module")
def map_125():
    return hh_map(0.125)


def test_a_chunk_copied_from_another_map_is_recomputed(tmp_path, map_125):
    hh_map(0.125, tmp_path / "a")
    hh_map(0.1, tmp_path / "b")
    (tmp_path / "a" / "chunk_000001.npz").write_bytes(
        (tmp_path / "b" / "chunk_000001.npz").read_bytes())
    with pytest.warns(RuntimeWarning, match="chunk_000001.npz belongs to another chaos map"):
        r = hh_map(0.125, tmp_path / "a")
    assert np.array_equal(r.values, map_125.values, equal_nan=True)


def test_chunks_of_another_map_are_not_used_after_map_json_is_lost(tmp_path, map_125):
    """map.json lost, the map called with other parameters: every old
    chunk is recognised as another map's (98 of 98 values came back)."""
    hh_map(0.1, tmp_path)
    (tmp_path / "map.json").unlink()
    with pytest.warns(RuntimeWarning, match="belongs to another chaos map"):
        r = hh_map(0.125, tmp_path)
    assert np.array_equal(r.values, map_125.values, equal_nan=True)
    # The directory is this map's now: the same call resumes every chunk.
    again = hh_map(0.125, tmp_path)
    assert again.provenance.options["chunks_resumed"] == again.provenance.options["chunks"]
    assert json.loads((tmp_path / "map.json").read_text())["t_end"] == 20.0


def _edit_chunk(path, edit):
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    edit(arrays)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())


CHUNK_EDITS = {
    "values NaN": (lambda a: a.__setitem__("values", a["values"] * np.nan), "not finite"),
    "values infinite": (lambda a: a.__setitem__("values", a["values"] + np.inf), "not finite"),
    "state NaN": (lambda a: a.__setitem__("state", a["state"] * np.nan), "state is not finite"),
    "status unknown": (lambda a: a.__setitem__("status", a["status"] + 40), "unknown code"),
    "fewer values": (lambda a: a.__setitem__("values", a["values"][:2]), "values is"),
    "values as int": (lambda a: a.__setitem__("values", a["values"].astype(np.int64)),
                      "values is"),
    "other orbits": (lambda a: a.__setitem__("orbits", a["orbits"][::-1].copy()),
                     "other orbits"),
    "t_stop off the grid": (lambda a: a.__setitem__("t_stop", a["t_stop"] + 0.01), "t_stop"),
    "negative error": (lambda a: a.__setitem__("energy_error", -a["energy_error"] - 1),
                       "negative"),
    "an array missing": (lambda a: a.pop("max_error"), "max_error"),
    "an extra array": (lambda a: a.__setitem__("junk", np.zeros(4)), "junk"),
    "no store entry": (lambda a: a.pop("__store__"), "__store__"),
    "another chunk's name": (lambda a: a.__setitem__("__store__", np.array(
        str(a["__store__"]).replace("chunk_000001", "chunk_000002"))), "another name"),
    "counts negative": (lambda a: a.__setitem__("__store__", np.array(
        str(a["__store__"]).replace('"steps": ', '"steps": -'))), "counts"),
}


@pytest.mark.parametrize("case", sorted(CHUNK_EDITS))
def test_an_edited_chunk_is_recomputed(case, tmp_path, map_125):
    edit, why = CHUNK_EDITS[case]
    hh_map(0.125, tmp_path)
    path = tmp_path / "chunk_000001.npz"
    _edit_chunk(path, edit)
    with pytest.warns(RuntimeWarning, match="chunk_000001.npz is unreadable") as warned:
        r = hh_map(0.125, tmp_path)
    assert any(why in str(w.message) for w in warned), [str(w.message) for w in warned]
    assert np.array_equal(r.values, map_125.values, equal_nan=True)
    assert r.provenance.options["chunks_resumed"] == r.provenance.options["chunks"] - 1


def test_a_full_checkpoint_directory_warns_and_the_map_goes_on(tmp_path, monkeypatch, map_125):
    def full(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(st, "atomic_write", full)
    with pytest.warns(RuntimeWarning, match="No space left.*the chaos map goes on") as warned:
        r = hh_map(0.125, tmp_path)
    assert len([w for w in warned if "No space" in str(w.message)]) == 1
    assert np.array_equal(r.values, map_125.values, equal_nan=True)


# -- ensemble realisations -------------------------------------------------------

PARAMS = {"shape": 24, "W": 4.0, "beta": 1.0}


def block(model, seed):
    return model.initial_block(3, 1.0, seed=seed)


def small(seeds, path, **kw):
    return varint.ensemble(DDNLS, seeds, block, "dvd", 2.0, 0.1, params={**PARAMS, **kw},
                           t_out=4, checkpoint=path, progress=False)


def test_ensemble_realisations_are_checked(tmp_path):
    first = small([1, 2], tmp_path)
    path = tmp_path / "seed_2.npz"
    good = path.read_bytes()
    # Another seed's file under this seed's name.
    path.write_bytes((tmp_path / "seed_1.npz").read_bytes())
    with pytest.warns(RuntimeWarning, match="seed_2.npz is unreadable.*another name"):
        again = small([1, 2], tmp_path)
    assert np.array_equal(again["x1"], first["x1"])
    # An edited result inside.
    with np.load(io.BytesIO(good)) as z:
        arrays = {k: z[k] for k in z.files}
    inner = dict(np.load(io.BytesIO(arrays["result"].tobytes())))
    inner["energy_error"] = inner["energy_error"][:2]
    buf = io.BytesIO()
    np.savez(buf, **inner)
    arrays["result"] = np.frombuffer(buf.getvalue(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())
    with pytest.warns(RuntimeWarning, match="seed_2.npz is unreadable.*energy_error"):
        again = small([1, 2], tmp_path)
    assert np.array_equal(again["x1"], first["x1"])
    # An older format (no store entry) is run again.
    buf = io.BytesIO()
    first_result = varint.run(DDNLS(**PARAMS, seed=2), block(DDNLS(**PARAMS, seed=2), 2),
                              "dvd", 2.0, 0.1, seed=2, t_out=4, progress=False)
    first_result.save(buf)
    path.write_bytes(buf.getvalue())
    with pytest.warns(RuntimeWarning, match="no __store__ entry"):
        small([1, 2], tmp_path)
    with pytest.raises(CheckpointError, match="other parameters"):
        small([1], tmp_path, beta=2.0)


def test_a_full_ensemble_directory_warns_and_goes_on(tmp_path, monkeypatch):
    reference = small([1, 2], None)

    def full(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(st, "atomic_write", full)
    monkeypatch.setattr(ckpt, "atomic_file", _failing_atomic_file)
    with pytest.warns(RuntimeWarning, match="No space left"):
        r = small([1, 2], tmp_path)
    assert np.array_equal(r["x1"], reference["x1"])


def _failing_atomic_file(path, mode="wb"):
    raise OSError(28, "No space left on device")


# -- saved results ------------------------------------------------------------------

@pytest.fixture(scope="module")
def saved():
    r = varint.lyapunov_spectrum(HenonHeiles(), [0.0, 0.558, 0.23337397, 0.0], 10.0, t_out=5)
    buf = io.BytesIO()
    r.save(buf)
    with np.load(io.BytesIO(buf.getvalue())) as z:
        return r, {k: z[k] for k in z.files}


def _meta_edit(edit):
    def apply(arrays):
        meta = json.loads(str(arrays["__meta__"]))
        edit(meta)
        arrays["__meta__"] = np.array(json.dumps(meta))
    return apply


RESULT_EDITS = {
    "unknown class": (_meta_edit(lambda m: m.update({"class": "os.system"})), "class"),
    "provenance field of another type": (_meta_edit(
        lambda m: m["provenance"].update({"tau": "0.05"})), "provenance.tau"),
    "provenance field unknown": (_meta_edit(
        lambda m: m["provenance"].update({"shell": "rm"})), "provenance.shell"),
    "provenance counts negative": (_meta_edit(
        lambda m: m["provenance"]["counts"].update({"steps": -4})), "provenance.counts.steps"),
    "provenance timing not seconds": (_meta_edit(
        lambda m: m["provenance"].update({"timing": {"run": "1"}})), "provenance.timing.run"),
    "provenance timing negative": (_meta_edit(
        lambda m: m["provenance"].update({"timing": {"run": -1.0}})), "provenance.timing.run"),
    "a field unknown": (_meta_edit(lambda m: m.update({"__init__": 1})), "__init__"),
    "verdict flipped to accurate": (_meta_edit(lambda m: m["accuracy"].update(
        {"energy_error": 0.5, "conserved": {"energy": 0.5}, "accurate": True})),
        "accuracy.accurate"),
    "verdict not a verdict": (_meta_edit(lambda m: m.update({"accuracy": {"x": 1}})),
                              "accuracy"),
    "energy errors of another length": (
        lambda a: a.__setitem__("energy_error", a["energy_error"][:3]), "energy_error"),
    "exponents of another length": (
        lambda a: a.__setitem__("exponents", a["exponents"][:2]), "exponents"),
    "times not finite": (lambda a: a.__setitem__("t", a["t"] * np.nan), "'t'"),
    "status as float": (_meta_edit(lambda m: m.update({"status": 0.5})), "status"),
    "an array unknown": (lambda a: a.__setitem__("payload", np.zeros(3)), "payload"),
    "meta missing": (lambda a: a.pop("__meta__"), "__meta__"),
}


@pytest.mark.parametrize("case", sorted(RESULT_EDITS))
def test_an_edited_result_file_is_refused_naming_the_field(case, saved, tmp_path):
    _, arrays = saved
    arrays = dict(arrays)
    edit, field = RESULT_EDITS[case]
    edit(arrays)
    path = tmp_path / "r.npz"
    np.savez(path, **arrays)
    with pytest.raises(ValueError) as err:
        varint.load_result(path)
    assert str(path) in str(err.value) and field in str(err.value), str(err.value)


def test_a_saved_result_still_loads_whole(saved, tmp_path):
    r, arrays = saved
    path = tmp_path / "r.npz"
    np.savez(path, **arrays)
    back = varint.load_result(path)
    assert back.provenance == r.provenance and np.array_equal(back.exponents, r.exponents)
    with pytest.raises(ValueError, match="not an .npz archive"):
        varint.load_result(io.BytesIO(b"x0,y0\n1,2\n"))


def test_chunk_store_keys_name_the_call():
    a = {"kind": "chaos_map", "t_end": 10.0}
    assert st.call_key(a) == st.call_key(dict(reversed(list(a.items()))))
    assert st.call_key(a) != st.call_key({**a, "t_end": 10.000000000000002})
    assert cm._chunk_name(3) == "chunk_000003"


def test_every_result_class_loads_back_whole(tmp_path):
    """The validation of load_result accepts what every result class saves:
    series, dict fields, maps, sections, local exponents, ensembles. The
    runs are those of tests/test_tables.py and tests/test_xarray.py (the
    same kinds, indicators, vectors and orbits per kernel; other horizons
    and outputs), which run in the same worker (tests/conftest.py): their
    kernels, not ones of their own (about 30 CPU s cold)."""
    hh = HenonHeiles()
    R1 = [0.0, 0.558, 0.23337397, 0.0]
    grid = varint.section_grid(hh, 0.125, np.linspace(-0.3, 0.5, 3), np.linspace(-0.3, 0.3, 3))
    results = [
        varint.gali(hh, R1, 10.0, k=(2, 4), t_out=3),
        varint.megno(hh, np.array([R1, R1]), 10.0, t_out=3),
        varint.run(hh, R1, "fli", 10.0, t_out=3),
        varint.run(hh, R1, "local_exponents", 10.0, window=4.0, n_exponents=2,
                   t_out=[1.0, 8.0]),
        varint.integrate(hh, R1, 10.0, t_out=3),
        varint.chaos_map(hh, grid, "sali", t_end=5.0, progress=False),
        varint.surface_of_section(hh, R1, 20.0),
        varint.ensemble(DDNLS, [1, 2], block, "dvd", 2.0, tau=0.1,
                        params={"shape": 16, "W": 4, "beta": 0.04}, t_out=4, progress=False),
    ]
    for r in results:
        path = tmp_path / f"{type(r).__name__}.npz"
        r.save(path)
        back = varint.load_result(path)
        assert type(back) is type(r) and back.provenance == r.provenance


def test_a_checkpoint_with_values_undefined_at_first_resumes(tmp_path, monkeypatch):
    """A local exponent is NaN until its first window closes: a record that
    is NaN where the run itself makes NaN is not taken for an edit."""
    hh = HenonHeiles()
    R1 = [0.0, 0.558, 0.23337397, 0.0]
    kw = dict(window=20.0, t_out=[1.0, 2.0, 60.0, 100.0], tau=0.05)
    full = varint.run(hh, R1, "local_exponents", 100.0, **kw)
    assert np.isnan(full.local[0]).all()
    path = tmp_path / "local.ckpt"
    with monkeypatch.context() as patch:
        hook_advance(patch, "tm", lambda state: state.step >= 1200, stop)
        with pytest.raises(Stop):
            varint.run(hh, R1, "local_exponents", 100.0, checkpoint=path, checkpoint_interval=0,
                       **kw)
    assert len(ckpt.read(path).records) >= 2
    assert_bitwise_equal(varint.run(hh, R1, "local_exponents", 100.0, checkpoint=path, **kw),
                         full)
