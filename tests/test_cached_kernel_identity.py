"""A kernel loaded from numba's disk cache runs the code compiled for what
was asked, whichever processes compiled and cached it (varint.codecache).

Three ways it did not, each giving other bits (or a buffer written past
its end) in a process that loads kernels other processes compiled (the
test suite's two workers on a cold cache), or one that compiled a second
closure of a function:

* a race: numba writes a cache entry as read the index (what → data file),
  pick the first free data file number, write the index, write the data.
  Two processes saving two versions of one function at once — two closures
  of a part stepper, two signatures of a package kernel — can both pick
  number 1; the index then names the data the *other* process wrote. Here
  the two processes are paced by flag files through exactly that
  interleaving (A reads the index, B reads it, A writes the index, B writes
  the index and its data, A writes its data), and a third asks for each
  version: it got A's code for B (x*3 for x*5, a contiguous sum on a
  strided array) as a cache hit;
* one name for two bodies: numba names compiled code by qualified name and
  a counter of the process, so the same closure with other constants,
  compiled by two processes, got one symbol name for its helper; a process
  loading both ran the first one's helper in the second;
* a key that omits what is compiled in: a generated stepper was named by
  its accumulator update's source alone, so two closures of one update (a
  user's ``make_update(w)``) shared one stepper.

Each test here failed before the fix."""

import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

from numba import float64, njit, types
from varint import codecache
from varint.codecache import _SignedCacheFile, _TolerantCache

ROOT = Path(__file__).resolve().parent.parent

#: The pacing, patched into the class that writes numba's files: A waits at
#: its index write until B has read the index, B writes the index after A
#: did, and A writes its data after B wrote its own.
PACING = '''
import sys, time
from pathlib import Path

role, flags = sys.argv[1], Path(sys.argv[2])


def wait(name):
    deadline = time.monotonic() + 30      # never hang: go on unpaced
    while not (flags / name).exists() and time.monotonic() < deadline:
        time.sleep(0.01)


def mark(name):
    (flags / name).touch()


def pace(cls):
    save_index, save_data = cls._save_index, cls._save_data
    if role == "A":
        def paced_index(self, o):
            wait("B_read"); save_index(self, o); mark("A_index")

        def paced_data(self, n, d):
            wait("B_data"); save_data(self, n, d)
    elif role == "B":
        def paced_index(self, o):
            mark("B_read"); wait("A_index"); save_index(self, o)

        def paced_data(self, n, d):
            save_data(self, n, d); mark("B_data")
    else:
        return
    cls._save_index, cls._save_data = paced_index, paced_data
'''

#: Two closures of one function, x*3 (A) and x*5 (B), cached signed as
#: generated and skeleton kernels are (codecache.SignedCache).
CLOSURES = PACING + '''
from numba import njit
from varint import codecache

pace(codecache._SignedCacheFile)
c = {"A": 3.0, "B": 5.0}[role[-1]]


def make(c):
    def scale(x):
        return x * c
    return njit(cache=True)(scale)


f = make(c)
f._cache = codecache.SignedCache(f.py_func, b"k" * 32, Path(sys.argv[3]))
print(f(2.0))
'''

#: Two signatures of one package kernel (contiguous for A, strided for B),
#: cached by numba under varint's _TolerantCache.
SIGNATURES = PACING + '''
import numpy as np
from numba import njit
from numba.core import caching
from varint import codecache

pace(caching.IndexDataCacheFile)


@njit(cache=True)
def total(a):
    s = 0.0
    for i in range(a.size):
        s += a[i]
    return s


total._cache = codecache._TolerantCache(total._cache)
a = np.arange(10.0)
print(total(a) if role[-1] == "A" else total(a[::2]))
'''


def race(tmp_path, code, *extra, env=None):
    """Run ``code`` as processes A and B at once, paced, then as a fresh
    loader of each version: their printed values (A, B, load A, load B),
    and how many data files A and B left (one: they collided)."""
    script = tmp_path / "race.py"
    script.write_text(textwrap.dedent(code))
    flags = tmp_path / "flags"
    flags.mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT), **(env or {}))

    def start(role):
        return subprocess.Popen([sys.executable, str(script), role, str(flags), *extra],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)

    def value(proc):
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err
        return float(out.split()[-1])

    a, b = start("A"), start("B")
    first = [value(a), value(b)]
    written = len(list(tmp_path.rglob("*.nbc")))
    return first + [value(start("load A")), value(start("load B"))], written


def test_two_closures_cached_at_once_each_load_their_own(tmp_path):
    folder = tmp_path / "closures"
    folder.mkdir()
    values, written = race(tmp_path, CLOSURES, str(folder),
                           env={"VARINT_CACHE_DIR": str(tmp_path / "cache")})
    assert written == 1         # the pacing made the collision: both wrote file 1
    assert values == [6.0, 10.0, 6.0, 10.0]


def test_two_signatures_cached_at_once_each_load_their_own(tmp_path):
    cache = tmp_path / "numba"
    values, written = race(tmp_path, SIGNATURES, env={"NUMBA_CACHE_DIR": str(cache)})
    assert written == 1
    # 0+1+…+9, and 0+2+4+6+8 (the contiguous kernel sums 0+1+2+3+4 = 10).
    assert values == [45.0, 20.0, 45.0, 20.0]


def test_a_data_file_is_used_only_for_its_own_key(tmp_path):
    """The file layer alone: an index entry naming another key's data (as
    the race leaves it) is a miss, the key's own data is found."""
    files = _SignedCacheFile(str(tmp_path), "kernel", ("stamp", 1))
    files.key = b"k" * 32
    files.save("B", "code of B")
    files.save("A", "code of A")
    assert (files.load("A"), files.load("B")) == ("code of A", "code of B")
    index = files._load_index()
    index["B"] = index["A"]                 # B's entry names A's data
    files._save_index(index)
    assert files.load("B") is None
    assert files.load("A") == "code of A"
    files.save("B", "code of B")            # compiled again: written over
    assert (files.load("A"), files.load("B")) == (None, "code of B")


def test_data_of_an_older_varint_is_a_miss(tmp_path):
    """A signed data file holding numba's data without its key (written
    before keys were stored) is not used."""
    files = _SignedCacheFile(str(tmp_path), "kernel", ("stamp", 1))
    files.key = b"k" * 32
    files.save("A", "code of A")
    name = files._load_index()["A"]
    files._save_data(name, "code of A")     # the old layout: data alone
    assert pickle.loads(codecache.read_signed(files._data_path(name), key=files.key)) == \
        "code of A"
    assert files.load("A") is None


def test_a_package_kernel_of_another_signature_is_a_miss():
    """_TolerantCache: code loaded for one signature but compiled for
    another (the race's outcome) is not used."""

    @njit
    def twice(x):
        return 2 * x

    twice(1.0)
    compiled = twice.overloads[(float64,)]

    class Inner:
        def load_overload(self, sig, target_context):
            return compiled

    cache = _TolerantCache(Inner())
    assert cache.load_overload((float64,), None) is compiled
    assert cache.load_overload((types.int64,), None) is None


#: A closure kernel calling a closed-over helper too long to be inlined,
#: cached under a key naming its constant c (as the skeleton's closures are,
#: varint.kernels.closures); prints, for each c asked, whether the kernel
#: (from the cache when there) gives the bits of one compiled afresh.
HELPER = """
import math, sys
from pathlib import Path
from numba import njit
from numba.core.caching import NullCache
from varint.kernels.closures import _ClosureCache


def make(c, cached=True):
    @njit
    def helper(x):
        s = 0.0
BODY
        return s

    def kernel(x):
        return helper(x) + helper(x + 1.0) + helper(x + 2.0)

    f = njit(kernel)
    f._cache = (_ClosureCache(f.py_func, f"c={c}", b"k" * 32, Path(sys.argv[1])) if cached
                else NullCache())
    return f


for c in map(float, sys.argv[2:]):
    f = make(c)
    print(c, f(0.5).hex(), make(c, cached=False)(0.5).hex(), sum(f.stats.cache_hits.values()))
""".replace("BODY", "\n".join(f"        s = s * 1.0000001 + math.sin(s + {i}.0 * x) * c"
                               for i in range(60)))


def test_closures_compiled_by_two_processes_run_their_own_helpers(tmp_path):
    """Process 1 compiles the kernel for c = 3, process 2 for c = 5 (each
    its first compilations: the same counter values); a third loads both,
    in both orders."""
    script, folder = tmp_path / "helper.py", tmp_path / "closures"
    script.write_text(HELPER)
    folder.mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT), VARINT_CACHE_DIR=str(tmp_path / "cache"))

    def run(*cs):
        done = subprocess.run([sys.executable, str(script), str(folder), *cs], env=env,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return [line.split() for line in done.stdout.splitlines()]

    (_, three, _, _), = run("3")
    (_, five, _, _), = run("5")
    assert three != five
    for order in (("3", "5"), ("5", "3")):
        rows = run(*order)
        assert [hits for *_, hits in rows] == ["1", "1"]        # both from the cache
        assert [got == afresh for _, got, afresh, _ in rows] == [True, True], order


#: A user's indicator whose accumulator update is a closure over a weight w
#: (aux += w log r); prints w and the accumulated value (hex) per run.
WEIGHTED = """
import sys
import numpy as np
from numba import njit
import varint
from varint.indicators import Indicator
from varint.protocol import Accumulator
from varint.results import IndicatorResult


def make_update(w):
    @njit
    def update(aux, r, x, W, flow, t):
        for j in range(r.shape[0]):
            aux[j, 0] += w * np.log(r[j])
    return update


def read(rows, model, t, options):
    return {"s": rows.extra["acc_sum"][:, 0, 0].copy()}


model, c1 = varint.paper_orbit("C1")
for w in sys.argv[1:]:
    varint.register_indicator(Indicator(
        name=f"weighted_{w}", summary="weighted log stretching", renorm="normalize",
        vectors=lambda model, options, given: 1, read=read, result=IndicatorResult,
        accumulator=Accumulator(name="sum", columns=("s",), initial=(0.0,),
                                update=make_update(float(w)))))
    r = varint.run(model, c1, f"weighted_{w}", t_end=10.0, tau=0.05, t_out=np.array([10.0]))
    print(w, float(r["s"][-1]).hex())
"""


def test_two_closures_as_accumulator_updates_each_run_their_own(tmp_path):
    """Hénon–Heiles has a generated stepper, into which the update is
    compiled. Named by its source alone, the update of w = 2 shared the
    stepper of w = 1 (in the process, and through the cache in the next
    one): the same value instead of twice it (multiplying by 2 is exact, so
    the sum of 2·log r is twice the sum of log r bit for bit)."""
    script = tmp_path / "weighted.py"
    script.write_text(WEIGHTED)
    env = dict(os.environ, PYTHONPATH=str(ROOT), VARINT_CACHE_DIR=str(tmp_path / "cache"))

    def run(*ws):
        done = subprocess.run([sys.executable, str(script), *ws], env=env,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        return [float.fromhex(line.split()[1]) for line in done.stdout.splitlines()]

    one, two = run("1", "2")
    assert one != 0.0 and two == 2 * one
    assert run("2") == [two]
