"""The collector is held off while varint loads code, and only then
(:mod:`varint.collector`): restored after every block, left disabled when
the user disabled it, shared by threads, and never held while numba
compiles (a cache miss returns before the compilation)."""

import gc
import threading

import pytest

from varint import codecache, collector


@pytest.fixture(autouse=True)
def _enabled():
    was = gc.isenabled()
    gc.enable()
    yield
    (gc.enable if was else gc.disable)()


def test_held_disables_and_restores_even_on_errors():
    with collector.held():
        assert not gc.isenabled()
        with collector.held():
            assert not gc.isenabled()
        assert not gc.isenabled()       # the outer block still loads
    assert gc.isenabled()
    with pytest.raises(KeyError), collector.held():
        raise KeyError("x")
    assert gc.isenabled()


def test_a_disabled_collector_stays_disabled():
    gc.disable()
    with collector.held():
        pass
    assert not gc.isenabled()


def test_a_block_that_made_many_objects_leaves_them_in_the_old_generation():
    """Code loaded while the collector was held (many new objects) is moved
    to the oldest generation by one young pass at the block's end, so that
    later young passes do not traverse it twice; a small block (a kernel
    read back) leaves the generations as they were, and so does a block
    whose user had disabled the collector."""
    def made(n):
        return [[] for _ in range(n)]       # lists: objects the collector tracks

    gc.collect()
    small_threshold = collector._PROMOTE * gc.get_threshold()[0]
    with collector.held():
        many = made(2 * small_threshold)
    # Tracked and in neither young generation: in the oldest (listing the
    # oldest instead took 1.9 CPU s in a process of a long suite's 3e6
    # objects, the young ones 1 ms).
    young = {id(o) for g in (0, 1) for o in gc.get_objects(generation=g)}
    assert all(gc.is_tracked(o) and id(o) not in young for o in many)
    assert gc.get_count()[0] < gc.get_threshold()[0]

    gc.collect()
    with collector.held():
        few = made(gc.get_threshold()[0] // 2)
    young = {id(o) for o in gc.get_objects(generation=0)}
    assert all(id(o) in young for o in few)

    gc.collect()
    gc.disable()
    with collector.held():
        kept = made(2 * small_threshold)
    young = {id(o) for o in gc.get_objects(generation=0)}
    assert all(id(o) in young for o in kept)


def test_threads_share_it_until_the_last_block_ends():
    inside, release, done = threading.Event(), threading.Event(), threading.Event()

    def other():
        with collector.held():
            inside.set()
            release.wait(10)
        done.set()

    thread = threading.Thread(target=other)
    thread.start()
    assert inside.wait(10)
    with collector.held():
        pass
    assert not gc.isenabled()           # the other thread is still loading
    release.set()
    assert done.wait(10)
    thread.join()
    assert gc.isenabled()


class _Inner:
    """A numba cache stand-in recording whether the collector ran."""

    def __init__(self, result):
        self.result, self.seen = result, []

    def load_overload(self, sig, target_context):
        self.seen.append(gc.isenabled())
        return self.result


def test_a_package_kernel_load_holds_it_and_a_miss_returns_it():
    inner = _Inner(None)                # a miss: numba then compiles, outside
    cache = codecache._TolerantCache(inner)
    assert cache.load_overload("float64(float64)", None) is None
    assert inner.seen == [False]
    assert gc.isenabled()
