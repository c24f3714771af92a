"""The CUDA backend (varint.gpu): the generated kernels against the CPU path.

Without a GPU the kernels run on numba's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1``, set before numba.cuda is imported, hence in a
subprocess): the same generated source, thread by thread in Python, on small
maps. The promise checked: bitwise the CPU's values, stopping times, status,
final states and energy errors for polynomial potentials, within 1e-12 relative otherwise
(on the simulator, whose exp is the CPU's, also bitwise). Tests marked
``cuda`` need a real GPU and skip without one.
"""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import varint
from varint.gpu import device, emit

pytest.importorskip("numba.cuda")

# Run in a subprocess on the simulator, with one of the runs below as its
# argument (JSON); prints one JSON line of checks.
_SIM_SCRIPT = r'''
import json, sys, numpy as np, sympy as sp, varint
import varint.gpu.advance as advance
from varint.gpu.resident import STAGES
from varint.methods import make_propagator
from varint.state import RunState, initial_deviations
from varint.models import HenonHeiles

launched = []
real = advance.advance_cuda
def counted(prop, module, state, n, snaps, active):
    launched.append(len(active))
    return real(prop, module, state, n, snaps, active)
advance.advance_cuda = counted   # the TM propagator imports it at each GPU call

def same(a, b):
    return all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)
               for f in ("values", "t_stop", "status", "state"))

def energy_gap(a, b):
    """The GPU's energies are its own (varint.gpu.energy): the largest
    difference of the energy errors (relative to the energy scale already),
    whether the same orbits have one, and whether the verdicts agree."""
    ok = np.isfinite(a.energy_error)
    gap = max(float(np.max(np.abs(a.energy_error[ok] - b.energy_error[ok]), initial=0.0)),
              float(np.nanmax(np.abs(a.accuracy.energy_error - b.accuracy.energy_error),
                              initial=0.0)))
    return [gap, bool(np.array_equal(ok, np.isfinite(b.energy_error))),
            bool(np.array_equal(a.accuracy.accurate, b.accuracy.accurate))]

def rel(a, b):
    ok = np.isfinite(a.values)
    return float(np.max(np.abs(a.values[ok] - b.values[ok]) / np.abs(a.values[ok])))

run = json.loads(sys.argv[1])
hh = HenonHeiles()
rng = np.random.default_rng(7)
X = np.zeros((10, 4))
X[:, 1] = rng.uniform(-0.25, 0.35, 10)
X[:, 2] = rng.uniform(0.05, 0.35, 10)
X[:, 3] = rng.uniform(0.05, 0.3, 10)
X = X[:run["orbits"]]
out = {}
for case in run["cases"]:
    ind, scheme = case.split("/")
    kw = dict(t_end=run["t_end"], tau=0.05, threshold=None, progress=False, scheme=scheme)
    n0 = len(launched)
    cpu = varint.chaos_map(hh, X, ind, **kw)
    gpu = varint.chaos_map(hh, X, ind, backend="cuda", **kw)
    out[f"{ind}/{scheme}"] = [same(cpu, gpu), len(launched) > n0]
    out[f"energy {ind}/{scheme}"] = energy_gap(cpu, gpu)
# The verdict with a tolerance that splits the orbits (the run's
# energy_tol lies between their errors): the same orbits are trusted.
kw = dict(t_end=run["t_end"], tau=0.05, threshold=None, progress=False,
          energy_tol=run["energy_tol"])
cpu = varint.chaos_map(hh, X, "fli", **kw)
gpu = varint.chaos_map(hh, X, "fli", backend="cuda", **kw)
out["verdict"] = energy_gap(cpu, gpu) + [int(cpu.accuracy.accurate.sum())]
# Early stopping (SALI below the threshold decides) at H = 0.16, where
# chaotic orbits decide within the run's horizon and others do not: the
# same stopping times, values and states.
y, py = rng.uniform(-0.3, 0.5, 10), rng.uniform(-0.2, 0.2, 10)
px = np.sqrt(np.maximum(2 * (0.16 - (y * y / 2 - y ** 3 / 3)) - py * py, 0.0))
C = np.column_stack([np.zeros(10), y, px, py])[:run["early_orbits"]]
kw = dict(t_end=run["early_t_end"], tau=0.05, threshold=run["early_threshold"],
          progress=False)
cpu = varint.chaos_map(hh, C, "sali", **kw)
before = dict(STAGES)
gpu = varint.chaos_map(hh, C, "sali", backend="cuda", chunk_size=run["chunk_size"], **kw)
out["early"] = [same(cpu, gpu), int((cpu.status == -1).sum())]
out["early_stages"] = {key: STAGES[key] - before[key]
                       for key in ("uploads", "compactions", "launches")}
# The state stays on the device between calls of a run: uploaded once; a
# call on the CPU in between (the host's rows change) makes the next GPU
# call upload it again; bitwise the CPU's run throughout.
W0 = initial_deviations(4, 2, len(X), 3)
p_cpu = make_propagator("tm", hh, 0.05, "qr")
p_gpu = make_propagator("tm", hh, 0.05, "qr", backend="cuda")
a = RunState.start(X, W0)
p_cpu.advance(a, 35)
b = RunState.start(X, W0)
u0 = STAGES["uploads"]
p_gpu.advance(b, 10)
p_gpu.advance(b, 10)
kept = STAGES["uploads"] - u0
p_cpu.advance(b, 5)
p_gpu.advance(b, 10)
out["resident"] = [all(np.array_equal(getattr(a, f), getattr(b, f))
                       for f in ("x", "W", "acc_m", "acc_e", "status", "step"))
                   and all(np.array_equal(a.extra[key], b.extra[key]) for key in a.extra),
                   kept, STAGES["uploads"] - u0]
# The work counted per call (gradients, Hessians, ...) is the CPU's, also
# when the GPU's bookkeeping skips the arrays of all orbits (no failure).
c1, c2 = RunState.start(X, W0), RunState.start(X, W0)
for steps in (7, 13):
    p_cpu.advance(c1, steps)
    p_gpu.advance(c2, steps)
out["counts"] = [c1.counts == c2.counts, c1.step == c2.step, c1.counts["steps"]]
# Page-locked buffers are allocated once: a second map of the same size
# takes them from the pool its first map's states returned them to.
import gc
kw = dict(t_end=run["pool_t_end"], tau=0.05, threshold=None, progress=False, backend="cuda")
varint.chaos_map(hh, X, "fli", **kw)
gc.collect()
alloc = STAGES["alloc"]
varint.chaos_map(hh, X, "fli", **kw)
out["pool"] = STAGES["alloc"] - alloc
# Escapes (E > 1/6): failed on the GPU, recomputed by the CPU's stepper.
E = np.array([[0.0, 0.1, 0.6, 0.1], [0.0, 0.0, 0.3, 0.2], [0.05, 0.0, 0.7, 0.0]])
kw = dict(t_end=run["escape_t_end"], tau=0.05, threshold=None, progress=False,
          escape_radius=3.0)
cpu = varint.chaos_map(hh, E, "fli", **kw)
gpu = varint.chaos_map(hh, E, "fli", backend="cuda", **kw)
out["escape"] = [same(cpu, gpu), int((cpu.status > 0).sum())]
out["energy escape"] = energy_gap(cpu, gpu)
# A from_potential model with exp (not polynomial): within 1e-12.
q0, q1 = sp.symbols("q0 q1")
toda = varint.models.from_potential(sp.exp(q1 + 2 * sp.sqrt(3) * q0) / 24
                             + sp.exp(q1 - 2 * sp.sqrt(3) * q0) / 24
                             + sp.exp(-2 * q1) / 24 - sp.Rational(1, 8), [q0, q1], name="toda")
T = np.array([[0.0, 0.0, 0.35, 0.25], [0.1, -0.1, 0.3, 0.3], [0.0, 0.2, 0.4, 0.1]])
kw = dict(t_end=run["toda_t_end"], tau=0.05, threshold=None, progress=False)
cpu = varint.chaos_map(toda, T, "fli", **kw)
gpu = varint.chaos_map(toda, T, "fli", backend="cuda", **kw)
out["toda"] = [rel(cpu, gpu), same(cpu, gpu)]
out["energy toda"] = energy_gap(cpu, gpu)
# The energy kernel alone, against the model's own NumPy energy, at states
# spread over each model's range: |H_gpu − H_cpu| / (|T| + |V|).
from numba import cuda
from varint.gpu import energy as genergy
masses = varint.models.from_potential(q0 ** 4 / 4 + q0 ** 2 * q1 - q1 ** 3 / 5 + q1 ** 2 / 2,
                                      [q0, q1], inverse_mass=[2.0, sp.Rational(1, 3)],
                                      name="masses")
gaps = {}
for name, model in (("hh", hh), ("toda", toda), ("masses", masses)):
    S = rng.uniform(-0.6, 0.6, (3, 4, 50))
    dev = cuda.device_array((3, 50))
    genergy.energy_kernel(model).launch(50, cuda.to_device(S), 3, dev)
    states = np.moveaxis(S, 1, 2)
    scale = model.energy_scale(states)
    gaps[name] = [float(np.max(np.abs(dev.copy_to_host() - model.energy(states)) / scale)),
                  genergy.supported(model)]
out["energy kernel"] = gaps
# The initial energies of a GPU run on the device (T and V, for H0 and
# the scale |T| + |V|): within 1e-15 of the scale of the host's, once per
# map over all its orbits.
from varint import accuracy
ref_gaps, calls = {}, []
for name, model in (("hh", hh), ("toda", toda), ("masses", masses)):
    S = rng.uniform(-0.6, 0.6, (50, 4))
    host, dev = accuracy.Reference(model, S), accuracy.Reference(
        model, S, genergy.kinetic_and_potential(model, S))
    scale = host.scales["energy"]
    ref_gaps[name] = max(float(np.max(np.abs(host.values["energy"] - dev.values["energy"])
                                      / scale)),
                         float(np.max(np.abs(host.scales["energy"] - dev.scales["energy"])
                                      / scale)))
real_parts = genergy.kinetic_and_potential
genergy.kinetic_and_potential = lambda m, x: (calls.append(len(x)), real_parts(m, x))[1]
varint.chaos_map(hh, X, "fli", t_end=run["pool_t_end"], tau=0.05, threshold=None,
                 progress=False, backend="cuda", chunk_size=4)
genergy.kinetic_and_potential = real_parts
out["reference"] = [ref_gaps, calls, len(X)]
print(json.dumps(out))
'''


#: The simulated runs. The simulator steps every GPU thread in Python, and
#: each (model, indicator, scheme) compiles a CPU stepper for the reference:
#: a check costs its orbits × steps and its kernels. ``QUICK`` (the default
#: suite, ~1 min) checks each property at the smallest size that shows it:
#:
#: * 6 orbits: fewer than the CPU's 8 SIMD lanes, so the reference is the
#:   one-orbit stepper (one compilation instead of two; the lanes equal it
#:   bit for bit, tests/test_generated_stepper.py);
#: * 80 steps: past the first check step (64), two output steps per map;
#:   the verdict's energy_tol (8.5e-8) lies between the orbits' errors at
#:   t = 4 (5.0e-8 to 1.14e-7; 4 of 6 trusted);
#: * no megno/SBAB2C: MEGNO's accumulator is emitted for megno/SABA2C, the
#:   scheme for fli, sali and gali;
#: * early stopping: SALI at H = 0.16 below 0.1 (a chaotic orbit decides at
#:   t ≈ 10, the others not by t = 12; below 1e-2 the first decides at
#:   t ≈ 30): one chunk of three drops a decided orbit on the device;
#: * the escape at t ≈ 13.6 within t = 15; Toda's exp over 200 steps;
#:   the pools and the reference over 10 steps.
#:
#: ``FULL`` (slow, ~4 min CPU) is the run these checks had before: 10 orbits
#: (the CPU's lanes), t = 10, all six (indicator, scheme), SALI below 1e-2
#: up to t = 60, the escapes to t = 30, Toda to t = 100.
QUICK = {"orbits": 6, "t_end": 4,
         "cases": ["fli/SBAB2C", "sali/SBAB2C", "fli/ABA864", "megno/SABA2C", "gali/SBAB2C"],
         "energy_tol": 8.5e-8, "early_orbits": 6, "early_t_end": 12, "early_threshold": 0.1,
         "chunk_size": 2, "pool_t_end": 0.5, "escape_t_end": 15, "toda_t_end": 10}
FULL = {"orbits": 10, "t_end": 10,
        "cases": ["fli/SBAB2C", "sali/SBAB2C", "megno/SBAB2C", "fli/ABA864", "megno/SABA2C",
                  "gali/SBAB2C"],
        "energy_tol": 9e-8, "early_orbits": 10, "early_t_end": 60, "early_threshold": 1e-2,
        "chunk_size": 4, "pool_t_end": 2, "escape_t_end": 30, "toda_t_end": 100}


@pytest.fixture(scope="module", params=[QUICK, pytest.param(FULL, marks=pytest.mark.slow)],
                ids=["quick", "full"])
def simulated(request):
    """The script's checks, and the run they were made with (``"run"``)."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    run = subprocess.run([sys.executable, "-c", _SIM_SCRIPT, json.dumps(request.param)],
                         env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    return dict(json.loads(run.stdout.strip().splitlines()[-1]), run=request.param)


def test_simulated_kernel_is_bitwise_the_cpu(simulated):
    """Every (indicator, scheme) of the run: the map ran on the (simulated)
    GPU, and its values, stopping times, status and states are the CPU's."""
    cases = simulated["run"]["cases"]
    assert not [case for case in cases if not simulated[case][1]], "not run on the GPU"
    assert not [case for case in cases if not simulated[case][0]], "not bitwise the CPU"


def test_simulated_energy_errors_within_1e_12_of_the_hosts(simulated):
    """The energies computed on the device (varint.gpu.energy) give energy
    errors within 1e-12 of the energy scale of the host's, for the same
    orbits, and the same accuracy verdicts: every (indicator, scheme), the
    escapes and Toda's exp."""
    for case in simulated["run"]["cases"] + ["escape", "toda"]:
        gap, same_orbits, same_verdict = simulated[f"energy {case}"]
        assert gap <= 1e-12 and same_orbits and same_verdict, (case, simulated[f"energy {case}"])


def test_simulated_verdict_is_the_cpus_where_the_tolerance_splits_the_orbits(simulated):
    gap, same_orbits, same_verdict, trusted = simulated["verdict"]
    assert 0 < trusted < simulated["run"]["orbits"], trusted   # the tolerance does split them
    assert same_verdict and same_orbits and gap <= 1e-12


@pytest.mark.parametrize("model", ["hh", "toda", "masses"])
def test_simulated_energy_kernel_is_the_models_energy(simulated, model):
    """H on the device (polynomial, exp, unequal masses) against the
    model's NumPy energy: within 1e-14 of |T| + |V| (a few roundings of
    a sum of terms of that size)."""
    gap, supported = simulated["energy kernel"][model]
    assert supported and gap <= 1e-14, gap


def test_simulated_initial_energies_on_the_device(simulated):
    """A GPU map's reference (H0 and |T| + |V|) is computed on the device,
    once for all its orbits (not per chunk), within 1e-15 of the scale of
    the host's."""
    gaps, calls, m = simulated["reference"]
    assert m > 4   # more orbits than a chunk (chunk_size=4)
    assert all(g <= 1e-15 for g in gaps.values()), gaps
    assert calls == [m], calls


def test_energy_on_the_device_only_where_h_is_kinetic_plus_potential():
    """Models whose H has a rotating frame's terms, or that declare other
    conserved quantities, keep the host's energy."""
    from varint.gpu import energy

    assert energy.supported(varint.models.HenonHeiles())
    assert not energy.supported(varint.models.CR3BP(0.01))


def test_simulated_early_stopping_and_compaction_match(simulated):
    bitwise, decided = simulated["early"]
    assert decided > 0, "no orbit decided: the check proves nothing"
    assert bitwise


def test_simulated_compaction_happens_on_the_device(simulated):
    """A map with early stopping uploads its state once per chunk and drops
    the decided orbits on the device (compactions), not by a new upload."""
    stages = simulated["early_stages"]
    run = simulated["run"]
    chunks = -(-run["early_orbits"] // run["chunk_size"])
    assert stages["uploads"] == chunks
    assert stages["compactions"] > 0
    assert stages["launches"] > stages["uploads"]


def test_simulated_state_stays_on_the_device_until_the_host_writes_it(simulated):
    bitwise, kept, uploads = simulated["resident"]
    assert kept == 1, "the second call uploaded the state again"
    assert uploads == 2, "a call on the CPU in between was not noticed"
    assert bitwise


def test_simulated_work_counts_are_the_cpus(simulated):
    same_counts, same_step, steps = simulated["counts"]
    assert same_counts and same_step and steps == 20 * simulated["run"]["orbits"]


def test_simulated_pinned_buffers_are_reused(simulated):
    assert simulated["pool"] == 0.0, "the second map page-locked new buffers"


def test_simulated_failed_orbits_are_the_cpus(simulated):
    bitwise, failed = simulated["escape"]
    assert failed > 0
    assert bitwise


def test_simulated_transcendental_model_within_1e_12(simulated):
    relative, _ = simulated["toda"]
    assert relative <= 1e-12


def test_cuda_without_gpu_says_so_in_one_line():
    if device.available():
        pytest.skip("a GPU (or the simulator) is present")
    hh = varint.models.HenonHeiles()
    with pytest.raises(RuntimeError, match="backend='cuda'") as err:
        varint.chaos_map(hh, np.array([[0.0, 0.1, 0.3, 0.1]]), "fli", t_end=1, tau=0.05,
                         backend="cuda", progress=False)
    assert "\n" not in str(err.value)


def test_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="backend must be one of"):
        varint.chaos_map(varint.models.HenonHeiles(), np.array([[0.0, 0.1, 0.3, 0.1]]), "fli",
                         t_end=1, tau=0.05, backend="gpu", progress=False)


def test_auto_without_gpu_is_the_cpu():
    if device.available():
        pytest.skip("a GPU (or the simulator) is present")
    hh = varint.models.HenonHeiles()
    X = np.array([[0.0, 0.1, 0.3, 0.1], [0.0, -0.2, 0.35, 0.2]])
    kw = dict(t_end=5, tau=0.05, threshold=None, progress=False)
    a = varint.chaos_map(hh, X, "fli", **kw)
    b = varint.chaos_map(hh, X, "fli", backend="auto", **kw)
    assert np.array_equal(a.values, b.values)


def test_an_accumulator_compiled_for_the_cpu_is_not_emitted():
    import dataclasses

    # FLI's compiled update without its rule: called, not written out.
    acc = dataclasses.replace(varint.indicators.megno.FLI_ACCUMULATOR, name="mine", rule=None)
    assert not emit.emittable(acc)
    with pytest.raises(ValueError, match="compiled for the CPU only"):
        emit.cuda_source(varint.models.HenonHeiles(), [1, 0, 1], [False] * 3, 1, acc)


def _ptx_or_skip(kern, signature, exact):
    """The kernel's PTX; with ``exact=False`` as numba-cuda compiles by
    default (NVVM contracting multiplies and adds)."""
    from numba import cuda

    try:
        if exact:
            return kern.ptx(signature)
        return cuda.compile_ptx(kern.dispatcher.py_func, signature, cc=(9, 0))[0]
    except Exception as exc:   # no NVVM (numba-cuda without the CUDA toolkit's wheels)
        pytest.skip(f"cannot compile PTX here: {str(exc).splitlines()[0]}")


def test_kernel_compiles_to_registers_without_contraction():
    """The real kernel compiles (PTX, no GPU needed where NVVM is
    installed): no thread-local memory (the work arrays live in registers)
    and fewer fused operations than NVVM makes when left to contract (the
    explicit fma only)."""
    if device.simulated():
        pytest.skip("the simulator compiles nothing")
    from numba import types as T

    from varint.indicators.megno import FLI_ACCUMULATOR
    from varint.schemes import DRIFT, get_scheme, stage_arrays

    kinds, _, hc = stage_arrays(get_scheme("SBAB2C"), 0.05)
    kern = emit.cuda_stepper(varint.models.HenonHeiles(), kinds, (hc != 0) & (kinds != DRIFT), 1,
                             FLI_ACCUMULATOR)
    f2, f3, f4 = T.float64[:, ::1], T.float64[:, :, ::1], T.float64[:, :, :, ::1]
    i1, i2, i3 = T.int64[::1], T.int64[:, ::1], T.int64[:, :, ::1]
    sig = (f2, f3, f2, i2, i1, i1, i1, i1, T.int64, T.int64, T.float64, T.float64[::1],
           T.float64[::1], T.float64, T.int64, T.int64, f3, i1, f3, f4, f3, i3, f4)
    exact = _ptx_or_skip(kern, sig, True)
    loose = _ptx_or_skip(kern, sig, False)
    assert ".local" not in exact
    assert 0 < exact.count("fma.rn.f64") < loose.count("fma.rn.f64")
    # Every other product and sum explicitly rounded: ptxas fuses only those
    # without a rounding modifier.
    assert exact.count("mul.rn.f64") > 0
    assert re.search(r"\b(mul|add|sub)\.f64", exact) is None


def test_kernel_is_linked_without_link_time_optimisation():
    """The PTX that NVVM writes without contraction is the code that runs:
    with LTO (numba-cuda's default where nvJitLink is installed) nvJitLink
    compiles the kernel again and fuses a·b + c (varint.gpu.device)."""
    if device.simulated():
        pytest.skip("the simulator links nothing")
    kern = device.kernel(lambda x: None)
    assert kern.dispatcher.targetoptions["lto"] is False


@pytest.mark.cuda
def test_gpu_map_is_bitwise_the_cpu():
    if not device.available() or device.simulated():
        pytest.skip("no CUDA GPU")
    hh = varint.models.HenonHeiles()
    X = varint.section_grid(hh, 0.125, np.linspace(-0.45, 0.65, 24),
                            np.linspace(-0.45, 0.45, 24)).states
    kw = dict(t_end=100, progress=False)
    a = varint.chaos_map(hh, X, "fli", **kw)
    b = varint.chaos_map(hh, X, "fli", backend="cuda", **kw)
    assert np.array_equal(a.values, b.values, equal_nan=True)


_CLUSTER_SCRIPT = r'''
import json, os, numpy as np, varint
from distributed import Client
from varint.gpu.cluster import local_gpu_cluster
from varint.models import HenonHeiles

def launches():
    from varint.gpu.resident import STAGES
    return STAGES["launches"]

hh = HenonHeiles()
rng = np.random.default_rng(3)
X = np.zeros((12, 4))
X[:, 1] = rng.uniform(-0.25, 0.35, 12)
X[:, 2] = rng.uniform(0.05, 0.35, 12)
X[:, 3] = rng.uniform(0.05, 0.3, 12)
kw = dict(t_end=5, tau=0.05, threshold=None, progress=False)
cpu = varint.chaos_map(hh, X, "fli", **kw)
with local_gpu_cluster(2) as cluster, Client(cluster) as client:
    gpu = varint.chaos_map(hh, X, "fli", backend="cuda", client=client, chunk_size=3, **kw)
    seen = sorted(client.run(lambda: os.environ["CUDA_VISIBLE_DEVICES"]).values())
    ran = sorted(client.run(launches).values())
same = all(np.array_equal(getattr(cpu, f), getattr(gpu, f), equal_nan=True)
           for f in ("values", "t_stop", "status", "state"))
print(json.dumps({"same": same, "devices": seen, "launches": ran}))
'''


def test_simulated_gpus_of_a_dask_cluster_give_the_cpus_bits():
    """One worker per GPU (two simulated ones), chunks of 3 orbits spread
    over them: the CPU's map without chunking, bit for bit."""
    pytest.importorskip("distributed")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    run = subprocess.run([sys.executable, "-c", _CLUSTER_SCRIPT], env=env, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["devices"] == ["0", "1"]
    assert all(n > 0 for n in out["launches"]), "a worker ran no chunk on its GPU"
    assert out["same"]


def test_gpu_cluster_refuses_bad_devices():
    from varint.gpu import cluster

    if cluster.gpu_count() == 0:
        with pytest.raises(RuntimeError, match="no CUDA GPU was found"):
            cluster.local_gpu_cluster()
    else:
        with pytest.raises(ValueError, match="devices must be distinct GPUs"):
            cluster.local_gpu_cluster([0, 0])


@pytest.mark.parametrize("early", [False, True], ids=["at_the_end", "early_stopping"])
def test_map_reads_unjoined_blocks_as_the_joined_records(early):
    """A map chunk reads its records block by block (varint.maps._read_at,
    no join of every output: the GPU map's host work): each orbit's value
    and energy error at its output, and the largest errors up to it, are
    those read from the joined arrays by indexing and ``np.nanmax`` (NaN
    ignored; NaN where an orbit has none), bit for bit."""
    from varint.maps import _read_at
    from varint.records import Records

    rng = np.random.default_rng(11)
    m, sizes = 40, (3, 1, 4)
    n = sum(sizes)
    joined = {key: rng.standard_normal((n, m)) for key in ("value", "energy_error",
                                                             "max_error")}
    for arr in joined.values():
        arr[rng.random((n, m)) < 0.2] = np.nan
    joined["max_error"][:, 5] = np.nan   # an orbit without any finite error
    records, first = Records(), 0
    for size in sizes:
        records.extend({key: arr[first:first + size].copy() for key, arr in joined.items()},
                       size)
        first += size
    at = rng.integers(0, n, m) if early else np.full(m, n - 1)
    if early:
        at[:3] = (0, 3, n - 1)   # the first output, a block's first, the last
    value, energy, largest_energy, largest = _read_at(records, at)
    rows = np.arange(m)
    assert np.array_equal(value, joined["value"][at, rows], equal_nan=True)
    assert np.array_equal(energy, joined["energy_error"][at, rows], equal_nan=True)
    upto = np.arange(n)[:, None] <= at[None, :]
    with np.errstate(all="ignore"), pytest.warns(RuntimeWarning):
        for got, key in ((largest_energy, "energy_error"), (largest, "max_error")):
            want = np.nanmax(np.where(upto, joined[key], np.nan), axis=0)
            assert np.array_equal(got, want, equal_nan=True), key
    assert np.isnan(largest[5])


def test_map_reads_no_outputs_as_nan():
    from varint.maps import _read_at
    from varint.records import Records

    for arr in _read_at(Records(), np.full(6, -1)):
        assert arr.shape == (6,) and np.isnan(arr).all()


def test_host_buffers_are_reused_only_when_nothing_refers_to_them():
    """varint.gpu.host.empty hands a buffer out again once every array,
    view or slice of it is gone, never while one is held (a caller's
    snapshot is not overwritten), and gives arrays of the shape and dtype
    asked for."""
    from varint.gpu import host

    a = host.empty((3, 1000, 4), float)
    assert a.shape == (3, 1000, 4) and a.dtype == np.float64 and a.flags.c_contiguous
    a[...] = 1.0
    kept = a[1:, ::2]   # a view keeps the buffer
    address = a.__array_interface__["data"][0]
    del a
    b = host.empty((3, 1000, 4), float)
    assert b.__array_interface__["data"][0] != address
    b[...] = 2.0
    assert (kept == 1.0).all()
    del kept
    c = host.empty((2, 1000, 4), np.int64)   # fits in the freed buffer
    assert c.__array_interface__["data"][0] == address and c.dtype == np.int64
    assert host.empty((0, 5)).shape == (0, 5)


@pytest.mark.parametrize("which", ["all", "some"])
def test_map_arrays_back_in_map_order(which):
    """varint.maps._in_map_order: the chunks' arrays (a shuffle split in
    chunks) put back where the chunks' indices say, as a scatter through
    them does, bit for bit; orbits of chunks not done are NaN (status 0)."""
    from types import SimpleNamespace

    from varint.maps import _CHUNK_ARRAYS, _in_map_order

    rng = np.random.default_rng(4)
    m, dim = 23, 4
    order = rng.permutation(m)
    chunks = [order[i:i + 5] for i in range(0, m, 5)]
    done = {}
    for c in (3, 0, 4, 1, 2) if which == "all" else (4, 1):
        n = len(chunks[c])
        done[c] = SimpleNamespace(**{
            name: (rng.integers(-1, 3, n) if kind == "i" else
                   rng.standard_normal((n, dim) if name == "state" else n))
            for name, kind in _CHUNK_ARRAYS.items()})
    got = _in_map_order(m, dim, chunks, done)
    for (name, kind), arr in zip(_CHUNK_ARRAYS.items(), got, strict=True):
        want = np.full((m, dim) if name == "state" else m, np.nan)
        if kind == "i":
            want = np.zeros(m, dtype=np.int64)
        for c, chunk in done.items():
            want[chunks[c]] = getattr(chunk, name)
        assert arr.dtype == want.dtype and np.array_equal(arr, want, equal_nan=True), name


@pytest.mark.parametrize("reps", [1, 3])
def test_relative_errors_are_the_tiled_expressions_bits(reps):
    """varint.accuracy._relative (broadcast, then in place: the GPU map's
    energy errors without temporaries) gives the bits of
    ``np.abs(v - np.tile(v0, reps)) / np.tile(scale, reps)``, also for a
    reference of one number in a call of one output (the general path)."""
    from varint.accuracy import _relative

    rng = np.random.default_rng(2)
    m = 50
    v0 = rng.standard_normal(m) * 10.0 ** rng.integers(-5, 5, m)
    scale = np.abs(v0) + rng.random(m)
    v = np.tile(v0, reps) * (1 + 1e-9 * rng.standard_normal(reps * m))
    v[7] = np.nan
    want = np.abs(v - np.tile(v0, reps)) / np.tile(scale, reps)
    got = _relative(v, v0, scale, reps)
    assert got.shape == want.shape and np.array_equal(got, want, equal_nan=True)
    if reps == 1:
        assert np.array_equal(_relative(v, 0.5, 2.0, 1), np.abs(v - 0.5) / 2.0, equal_nan=True)
