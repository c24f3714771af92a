"""The fixed-cost profile's stages: every one is reached by the call it
profiles, each nests in its parent, and the wrappers leave varint as it
was; never a time compared with a figure."""

import importlib

import numpy as np

import varint
from studies import call_profile
from varint.models.potential_rows import NUMPY_POWER_IS_LIBM


def _original(path, name):
    """The function a stage names, or None where this code has none (an
    older tree's stage)."""
    module, _, attr = path.partition(":")
    owner = importlib.import_module(module)
    return getattr(getattr(owner, attr, None) if attr else owner, name, None)


def test_every_stage_is_reached_nests_in_its_parent_and_is_restored():
    model, x0 = varint.paper_orbit("R1")
    w = np.eye(4)[:, :1]
    before = [_original(path, name) for _, _, path, name in call_profile.STAGES]
    spent = {}
    restore = call_profile.wrap_stages(spent)
    try:
        # The first call is built from its arguments; the second repeats
        # them and runs as a remembered call (varint.remembered).
        for _ in range(2):
            varint.integrate(model, x0, 0.05, tau=0.05, scheme="s15odr8", deviations=w)
    finally:
        restore()
    # A stage the calls no longer go through (a renamed function) would be
    # missing here, and the stored breakdown would silently lose it.
    labels = [label for _, label, _, _ in call_profile.STAGES]
    assert sorted(spent) == sorted(labels)
    # Inclusive times: a stage's children (the deeper rows after it, up to
    # the next row as shallow as it) never take longer than it.
    for i, (depth, label, _, _) in enumerate(call_profile.STAGES):
        for d, child, _, _ in call_profile.STAGES[i + 1:]:
            if d <= depth:
                break
            assert spent[child] <= spent[label], (child, label)
    assert [_original(path, name) for _, _, path, name in call_profile.STAGES] == before


def test_every_stage_of_a_prepared_short_call_is_reached_and_restored():
    model, x0 = varint.paper_orbit("R1")
    run = varint.prepare(model, "integrate", 0.05, tau=0.05, scheme="s15odr8",
                         deviations=np.eye(4)[:, :1])
    run(x0)
    stages = call_profile.SHORT_STAGES
    before = [_original(path, name) for _, _, path, name in stages]
    spent = {}
    restore = call_profile.wrap_stages(spent, stages)
    try:
        run(x0)
    finally:
        restore()
    # This code passes every stage but the older code's (which the study
    # keeps to profile a baseline tree): a renamed stage would be missing.
    # (A set: two codes' stages may share a label, as the energy verdict's.)
    # Hénon–Heiles' V is compiled but for its cube only where NumPy's power
    # is not libm's (a CPU with AVX-512).
    numpy_powers = call_profile.SHORT_STAGES_NUMPY_POWERS
    assert set(spent) - numpy_powers == set(
        label for _, label, _, _ in stages
        if label not in call_profile.SHORT_STAGES_BEFORE_ROUND6
        and label not in call_profile.SHORT_STAGES_BEFORE_ROUND8
        and label not in call_profile.SHORT_STAGES_BEFORE_ROUND9) - numpy_powers
    assert bool(set(spent) & numpy_powers) == (not NUMPY_POWER_IS_LIBM)
    for i, (depth, label, _, _) in enumerate(stages):
        for d, child, _, _ in stages[i + 1:]:
            if d <= depth:
                break
            assert spent.get(child, 0.0) <= spent.get(label, 0.0), (child, label)
    assert [_original(path, name) for _, _, path, name in stages] == before


def test_as_on_avx512_the_short_call_passes_the_numpy_powers_stage(monkeypatch):
    from varint.models import potential_rows
    from varint.models.henon_heiles import HenonHeiles

    # (as_on_avx512, undone: the flag by monkeypatch, the memoised V here.)
    monkeypatch.setattr(potential_rows, "NUMPY_POWER_IS_LIBM", False)
    potential_rows.rows_from.cache_clear()
    try:
        _, x0 = varint.paper_orbit("R1")
        run = varint.prepare(HenonHeiles(), "integrate", 0.05, tau=0.05, scheme="s15odr8")
        run(x0)
        spent = {}
        restore = call_profile.wrap_stages(spent, call_profile.SHORT_STAGES)
        try:
            run(x0)
        finally:
            restore()
    finally:
        potential_rows.rows_from.cache_clear()
    assert set(spent) >= call_profile.SHORT_STAGES_NUMPY_POWERS
