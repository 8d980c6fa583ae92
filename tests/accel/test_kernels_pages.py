"""``accel.small_pages``: with ``small_pages=True`` (opt-in) NumPy's huge-page hint is off inside
shapeflow's heavy calls, and restored; by default shapeflow leaves it alone.

Independent of numba (the switch is NumPy's), so not skipped with the kernels.
"""

from __future__ import annotations

import threading

import meshgen
import pytest
from conftest import need

import shapeflow as sf
from shapeflow import accel as kernels

setter = kernels.madvise_setter()
pytestmark = pytest.mark.skipif(setter is None, reason="this NumPy has no huge-page switch")


def hint() -> bool:
    """NumPy's current setting (read by setting and restoring it)."""
    old = setter(False)
    setter(old)
    return bool(old)


@pytest.fixture(autouse=True)
def numpy_default():
    old = setter(True)
    with kernels.use(small_pages=True):      # the opt-in; threads started below see the default
        yield
    setter(old)


def test_by_default_the_hint_is_left_alone():
    m = meshgen.grid(6, 5, z=lambda x, y: 0.2 * x * y)
    seen = []
    with kernels.use(small_pages=False):
        sf.flow(m, 0.5, iterations=2, progress=lambda i, n: seen.append(hint()))
    assert seen == [True, True]


def test_off_inside_restored_after():
    with kernels.small_pages():
        assert hint() is False
        with kernels.small_pages():      # re-entrant
            assert hint() is False
        assert hint() is False
    assert hint() is True
    setter(False)                        # a caller's own choice is restored, not overwritten with True
    with kernels.small_pages():
        assert hint() is False
    assert hint() is False


def test_restored_after_an_exception():
    with pytest.raises(sf.MeshError):
        sf.Mesh([[0.0, 0.0, 0.0]], [[0, 1, 2]])          # validation fails inside Mesh.__init__
    assert hint() is True


def test_flow_runs_without_the_hint():
    m = meshgen.grid(6, 5, z=lambda x, y: 0.2 * x * y)
    seen = []
    sf.flow(m, 0.5, iterations=2, progress=lambda i, n: seen.append(hint()))
    assert seen and not any(seen)
    assert hint() is True


def test_interleaved_threads_restore_the_setting():
    """Thread A enters, B enters, A leaves, B leaves: off until the last one leaves."""
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    during = []

    def a():
        with kernels.use(small_pages=True), kernels.small_pages():
            a_in.set()
            b_in.wait(5)
        a_out.set()

    def b():
        a_in.wait(5)
        with kernels.use(small_pages=True), kernels.small_pages():
            b_in.set()
            a_out.wait(5)
            during.append(hint())

    ts = [threading.Thread(target=a), threading.Thread(target=b)]
    for t in ts:
        t.start()
    for t in ts:
        t.join(10)
    assert during == [False]
    assert hint() is True


def test_the_setting_is_per_thread():
    """``use(small_pages=True)`` in one thread does not reach another thread's calls."""
    seen = []
    old = kernels.set_default(small_pages=False)
    try:
        t = threading.Thread(target=lambda: seen.append(kernels.current().small_pages))
        t.start()
        t.join(10)
    finally:
        kernels.set_default(old)
    assert kernels.current().small_pages is True and seen == [False]


def test_thread_count_follows_the_setting_and_the_machine(monkeypatch):
    """threads="auto": the usable cores less the other runnable tasks (at least one); an integer is
    used as given; NUMBA_NUM_THREADS caps both."""
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    monkeypatch.setattr(kernels, "usable_cores", lambda: 4)
    for others, want in ((0, 4), (1, 3), (3, 1), (9, 1)):
        monkeypatch.setattr(kernels, "other_runnable", lambda o=others: o)
        with kernels.use(threads="auto"):
            assert kernels.thread_count() == want
    with kernels.use(threads=3):
        assert kernels.thread_count() == 3
    monkeypatch.setenv("NUMBA_NUM_THREADS", "2")
    with kernels.use(threads=3):
        assert kernels.thread_count() == 2
    with pytest.raises(sf.ParameterError, match="threads"):
        kernels.Backend(threads=0)


def test_a_call_restores_the_callers_numba_threads():
    numba = need("numba", "numba (the 'fast' extra)")
    m = meshgen.grid(6, 5, z=lambda x, y: 0.2 * x * y)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    before = numba.get_num_threads()
    seen = []
    with kernels.use(kernels="force", threads=1):
        sf.flow(m, -2.0, progress=lambda i, n: seen.append(numba.get_num_threads()))
    assert seen == [1] and numba.get_num_threads() == before
