"""A process forked after its parent ran numba's OpenMP threads computes with the NumPy twins.

GNU OpenMP ends a child forked after the parent used it as soon as the child starts a parallel
region ("fork() called from a process already using GNU OpenMP"); a ``multiprocessing.Pool`` then
waits for the dead worker's result forever.  The child's result is compared with the parent's own
NumPy/SciPy result (kernels off), which it must equal bit for bit.
"""

from __future__ import annotations

import logging
import multiprocessing
import sys

import meshgen
import numpy as np
import pytest

import shapeflow as sf
from shapeflow import accel

pytestmark = [
    pytest.mark.skipif(not accel.available(), reason="numba (the 'fast' extra) not installed"),
    pytest.mark.skipif(sys.platform != "linux", reason="the fork start method is Linux's default"),
]


def _mesh() -> sf.Mesh:
    return meshgen.grid(12, 10, jitter=0.1, seed=3, mix=0.4, z=lambda x, y: 0.2 * np.sin(x) * np.cos(y))


def _flow_forced(_):
    with accel.use(kernels="force"):
        return sf.flow(_mesh(), 3.0).vertices


def _layer() -> str:
    import numba

    with accel.use(kernels="force"):       # a parallel kernel in this process starts the threading layer
        sf.flow(_mesh(), 3.0)
    return numba.threading_layer()


def test_a_pool_forked_after_openmp_finishes_with_the_numpy_twins():
    if _layer() != "omp":
        pytest.skip("numba runs on a threading layer other than OpenMP here")
    with accel.use(kernels="off"):
        expected = sf.flow(_mesh(), 3.0).vertices
    with multiprocessing.get_context("fork").Pool(2) as pool:
        got = pool.map_async(_flow_forced, range(2)).get(timeout=120)   # a dead worker: TimeoutError
    for v in got:
        np.testing.assert_array_equal(v, expected)


def test_the_parent_keeps_its_compiled_kernels_and_the_child_says_why_once(caplog):
    if _layer() != "omp":
        pytest.skip("numba runs on a threading layer other than OpenMP here")
    ctx = multiprocessing.get_context("fork")
    r, w = ctx.Pipe(duplex=False)

    def child():
        records = []
        handler = logging.Handler()
        handler.emit = records.append
        logging.getLogger("shapeflow").addHandler(handler)
        uses = [accel.Backend(kernels="force").uses_compiled(10) for _ in range(3)]
        w.send((uses, [rec.getMessage() for rec in records]))

    p = ctx.Process(target=child)
    p.start()
    assert r.poll(120)
    uses, messages = r.recv()
    p.join(60)
    assert p.exitcode == 0
    assert uses == [False, False, False]
    assert len(messages) == 1 and "forked after its parent ran numba's OpenMP" in messages[0]
    assert accel.Backend(kernels="force").uses_compiled(10)        # the parent is untouched
