"""The planetary SIMD-lane kernels are cached on disk like the stepping
skeleton's other closure kernels: a second process runs a planetary map
without compiling and gets the same bits; their numba files are signed, and
one that is edited is never unpickled: it is discarded with a warning and
the kernel compiled again (varint.kernels.closures, issue 28)."""

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

from varint import codecache

ROOT = Path(__file__).resolve().parent.parent

#: A small MEGNO map of one planet's (a, e) about the Sun, stepped as SIMD
#: lanes (8 orbits): prints the seconds compiled, the map's values and the
#: warnings' text. One planet: the smallest lanes kernel, which compiles in
#: half the time of two planets' (27 s against 62 s of CPU on a cold cache).
MAP = """
import json, warnings
import varint
from varint import compiling
from varint.models import Planetary
model = Planetary([1.0, 0.000954])
grid = varint.element_grid(model, [dict(a=5.2, e=0.05, M=0.6, omega=0.3)], 1,
                           [4.0, 5.0, 6.0, 7.0], [0.05, 0.25])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    r = varint.chaos_map(model, grid, "megno", t_end=20.0, tau=1.0,
                         scheme=varint.get_scheme("SABA1"), progress=False)
print(json.dumps([compiling.compile_seconds(), r.values.tobytes().hex(),
                  [str(w.message) for w in caught]]))
"""


def fresh(cache_dir):
    """The map in a new interpreter on this source tree, with the cache
    directory ``cache_dir``: (seconds compiled, values, warnings)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), VARINT_CACHE_DIR=str(cache_dir),
               NUMBA_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", MAP], env=env, check=True,
                          capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def lane_files(cache_dir):
    return sorted((cache_dir / "closures").glob("planetary_batch.*.nb[ic]"))


def test_a_second_process_runs_a_planetary_map_without_compiling_and_edits_are_refused(
        tmp_path):
    """The lanes' batch kernel, compiled by one process, is loaded by the
    next, which compiles nothing and gets the same bits. Its numba files
    carry varint's signature; a pickle planted in their place (it would
    create a marker file when unpickled) is never loaded: the next process
    warns, compiles again, gets the same bits, and signs new files."""
    cache_dir = tmp_path / "cache"
    compiled, cold, _ = fresh(cache_dir)
    assert compiled > 0.0
    files = lane_files(cache_dir)
    assert {f.suffix for f in files} == {".nbi", ".nbc"}
    assert all(f.read_bytes().startswith(codecache.HEADER) for f in files)

    compiled, warm, caught = fresh(cache_dir)
    assert compiled == 0.0 and warm == cold
    assert not any("is not used" in w for w in caught)

    marker = tmp_path / "MARKER"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    data = [f for f in files if f.suffix == ".nbc"]
    for f in data:
        f.write_bytes(pickle.dumps(Payload()))
    compiled, again, caught = fresh(cache_dir)
    assert again == cold and not marker.exists()
    assert compiled > 0.0
    assert any("numba cache file" in w and "is not used" in w for w in caught)
    assert all(f.read_bytes().startswith(codecache.HEADER) for f in lane_files(cache_dir))
