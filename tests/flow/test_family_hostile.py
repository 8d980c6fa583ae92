"""family() on hostile λ, compiled kernels forced and off: λ so small that σ = 1/|λ| leaves the polynomial
preconditioner's range (and the compiled seed's recurrences meet 0 / 0) or double precision (subnormal λ),
and hundreds of members: no exception, no warning, every member finite and equal to flow() at its λ within
1e-7 of the diagonal.

And the family on any number of threads (the compiled seed, the factor's powers and the true-residual
check share their rows out by blocks of 4,096 rows whose sums are added in block order): the same bits
on 1, 2 and 3 threads at block boundaries, on tiny meshes and under hostile λ, weights and axes; from two
Python threads at once; beside a CPU-bound process; in forked children (the NumPy twins) and spawned ones.
"""

from __future__ import annotations

import logging
import multiprocessing
import subprocess
import sys
import threading
import warnings

import numpy as np
import pytest
from meshgen import cube_sphere, grid

import shapeflow as sf
from shapeflow import accel
from shapeflow.linalg import spd

TOL = 1e-7


@pytest.fixture(autouse=True)
def jacobi_flow(monkeypatch):
    """flow() with Jacobi-preconditioned CG, as in tests/flow/test_family.py (the two agree to the
    solves' tolerance)."""
    monkeypatch.setattr(spd, "DEFAULT_PRECONDITIONER", "jacobi")


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("lams", [[1e-200, -1e-100, -5.0, 0.0], list(np.linspace(-300.0, 300.0, 500))],
                         ids=["tiny", "500"])
def test_hostile_families_match_flow(kernels, lams):
    mesh = cube_sphere(6, mix=0.3)
    with accel.use(kernels=kernels), warnings.catch_warnings():
        warnings.simplefilter("error")
        shapes, report = sf.family(mesh, lams, return_report=True)
        assert report.path == "multishift" and np.isfinite(shapes).all()
        refs = {lam: sf.flow(mesh, lam).vertices for lam in set(lams)}
    worst = max(float(np.abs(shapes[m] - refs[lam]).max()) for m, lam in enumerate(lams))
    assert worst <= TOL * mesh.diagonal, worst


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("lams", [[5e-324], [1.0, 5e-324, -1e-308, 3e-309, 0.0, -4.0]], ids=["alone", "mixed"])
def test_subnormal_lams_are_flows(kernels, lams):
    # 1/|λ| overflows below 5.6e-309: such members are solved as flow() does, not handed to the shared
    # solve as an infinite shift (which refused them with "shifts must be finite")
    mesh = cube_sphere(6, mix=0.3)
    tiny = [m for m, lam in enumerate(lams) if lam != 0 and np.isinf(1.0 / abs(lam))]
    with accel.use(kernels=kernels, threads=2), warnings.catch_warnings():
        warnings.simplefilter("error")
        shapes, report = sf.family(mesh, lams, return_report=True)
        refs = np.stack([sf.flow(mesh, lam).vertices for lam in lams])
    assert np.abs(shapes - refs).max() <= TOL * mesh.diagonal
    if len(lams) == 1:
        assert report.path == "separate" and "overflows" in report.reason
    else:
        assert report.path == "multishift" and set(tiny) <= set(report.fallback_members) and len(tiny) == 2


# --------------------------------------------------------------------------
# the family on any number of threads
# --------------------------------------------------------------------------

needs_numba = pytest.mark.skipif(not accel.numba_available(), reason="the compiled kernels need numba")


def _bumps(x, y):
    return 0.3 * np.sin(0.7 * x) * np.cos(0.5 * y)


TET = sf.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
#: vertices (= rows of the shared system) one short of a block, one over, two blocks and one over (one
#: free column), beyond two blocks; four and nine vertices (one free): fewer rows than threads
MESHES = {"4095": lambda: grid(63, 65, z=_bumps, mix=0.3), "4097": lambda: grid(17, 241, z=_bumps, mix=0.2),
          "8193": lambda: grid(3, 2731, z=_bumps), "9602": lambda: cube_sphere(40, mix=0.3),
          "tet": lambda: TET, "3x3": lambda: grid(3, 3, z=lambda x, y: 1.0 * (x == 1) * (y == 1))}
FIGURE1 = list(np.arange(0.0, -240.0, -5.0))
HOSTILE = [1e12, -1e12, 5.0, 2.0, -2.0, 2.0, 0.0, -1e-300, 3e-309]


def family_on(threads, mesh, lams, kernels="force", **kw):
    with accel.use(kernels=kernels, threads=threads), warnings.catch_warnings():
        warnings.simplefilter("error")
        return sf.family(mesh, lams, **kw)


@needs_numba
@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.parametrize("lams", [FIGURE1, HOSTILE], ids=["figure1", "hostile"])
def test_the_family_gives_the_same_bits_on_any_number_of_threads(name, lams):
    # 3 threads is more than NUMBA_NUM_THREADS on a 2-core machine: capped, same result
    mesh = MESHES[name]()
    for kw in ({}, {"lam_border": 1.5}):
        one, two, three = (family_on(t, mesh, lams, **kw) for t in (1, 2, 3))
        assert np.array_equal(one, two) and np.array_equal(one, three)
        ref = family_on(1, mesh, lams, kernels="off", **kw)
        assert np.abs(one - ref).max() <= TOL * mesh.diagonal


@needs_numba
def test_weights_with_zeros_and_axes_subsets_on_two_threads():
    mesh = MESHES["9602"]()
    rng = np.random.default_rng(1)
    w = rng.uniform(0.0, 1.0, mesh.n_vertices)
    w[rng.random(mesh.n_vertices) < 0.3] = 0.0
    for kw in ({"weights": w}, {"weights": w, "invert_weights": True}, {"axes": (True, False, False)},
               {"axes": (False, True, True), "preserve_volume": True}):
        one, two = (family_on(t, mesh, FIGURE1, **kw) for t in (1, 2))
        assert np.array_equal(one, two), kw
        assert np.abs(two - family_on(1, mesh, FIGURE1, kernels="off", **kw)).max() <= TOL * mesh.diagonal


@needs_numba
def test_families_from_two_python_threads_at_once():
    # each Python thread its own accel.use (1, 2, 2 threads, "auto"): numba's thread count is per thread
    import numba

    mesh = MESHES["9602"]()
    want = family_on(1, mesh, FIGURE1)
    before = numba.get_num_threads()
    got, errors = {}, []

    def worker(i, threads):
        try:
            got[i] = [family_on(threads, mesh, FIGURE1) for _ in range(3)]
        except BaseException as exc:            # noqa: BLE001 - reported by the assertion below
            errors.append(exc)

    workers = [threading.Thread(target=worker, args=(i, t)) for i, t in enumerate((1, 2, 2, "auto"))]
    for t in workers:
        t.start()
    for t in workers:
        t.join(120)
    assert not errors and sorted(got) == [0, 1, 2, 3]
    # to rounding, not bit for bit: with a cold compiled-code cache one run in four gave a few members one
    # unit in the last place apart (none in six with OPENBLAS_NUM_THREADS=1); the thread count alone
    # never changes a bit (test_the_family_gives_the_same_bits_on_any_number_of_threads)
    ulp = 4 * np.finfo(np.float64).eps * np.abs(want).max()
    assert all(np.abs(s - want).max() <= ulp for runs in got.values() for s in runs)
    assert numba.get_num_threads() == before


@needs_numba
def test_a_family_beside_a_cpu_bound_process():
    # "auto" counts the busy process out (one thread here); 2 threads wait for it at every barrier:
    # slower, never different
    mesh = MESHES["9602"]()
    want = family_on(1, mesh, FIGURE1)
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        for threads in ("auto", 2):
            assert np.array_equal(family_on(threads, mesh, FIGURE1), want)
    finally:
        busy.kill()
        busy.wait()


def _child_family(mesh):
    """In a child process: its backend for a large problem, two families with the compiled kernels
    forced on two threads, and the shapeflow log lines."""
    records = []
    handler = logging.Handler()
    handler.emit = records.append
    logging.getLogger("shapeflow").addHandler(handler)
    runs = [family_on(2, mesh, FIGURE1) for _ in range(2)]
    with accel.use(kernels="force"):
        backend = accel.kernels("linalg", mesh.n_vertices).backend
    return backend, runs, [r.getMessage() for r in records]


@needs_numba
@pytest.mark.skipif(sys.platform != "linux", reason="the fork start method is Linux's")
def test_forked_and_spawned_children_run_families():
    # forked after the parent's parallel kernels ran on OpenMP: the NumPy twins, said once; spawned:
    # the compiled kernels, the parent's bits
    import numba

    mesh = MESHES["9602"]()
    compiled = family_on(2, mesh, FIGURE1)
    numpy = family_on(2, mesh, FIGURE1, kernels="off")
    forked = numba.threading_layer() == "omp"
    for method in ("fork", "spawn"):
        with multiprocessing.get_context(method).Pool(1) as pool:
            backend, runs, log = pool.apply_async(_child_family, (mesh,)).get(timeout=120)
        if method == "fork" and forked:
            assert backend == "numpy" and len(log) == 1 and "forked" in log[0]
            assert all(np.array_equal(r, numpy) for r in runs)
        else:
            assert backend == "numba" and not log
            assert all(np.array_equal(r, compiled) for r in runs)


# --------------------------------------------------------------------------
# the true-residual check behind the shared solve's factor
# --------------------------------------------------------------------------

@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("scale", [1.5, 1e100, 1e200])
def test_a_wrong_member_from_the_factor_is_solved_again(monkeypatch, kernels, scale):
    # one shift's row of the low-rank factor made wrong (finite): its members fail the true-residual
    # check and are solved as flow() does, however large the wrong values (1e200 × a displacement:
    # its squares overflow, which made the check's rounding allowance infinite and let it pass)
    from shapeflow.flow import family_paths

    mesh = cube_sphere(20, mix=0.3)
    lams = FIGURE1
    real = family_paths.MemberSink.factors
    hit = []

    def factors(self, lefts, Ws):
        for L in lefts:
            L[5] *= scale                   # shift 5 (in the solve's order), every column
        hit.extend(int(m) for m in self.member_of_shift[5])
        return real(self, lefts, Ws)

    monkeypatch.setattr(family_paths.MemberSink, "factors", factors)
    with accel.use(kernels=kernels), pytest.warns(sf.errors.SolverWarning, match="true"):
        shapes, report = sf.family(mesh, lams, return_report=True)
    assert hit and set(hit) <= set(report.fallback_members)
    refs = {lam: sf.flow(mesh, lam).vertices for lam in set(lams)}
    worst = max(float(np.abs(shapes[m] - refs[lam]).max()) for m, lam in enumerate(lams))
    assert worst <= TOL * mesh.diagonal, worst


@needs_numba
@pytest.mark.parametrize("axes", [(True, True, True), (False, True, False)], ids=["xyz", "y"])
def test_the_true_residual_check_in_the_seeds_block_filled_with_nan(monkeypatch, axes):
    # The check's scratch (n × 3 × RESIDUAL_MEMBERS values) fits in the seed's block once the shared
    # solve ran RESIDUAL_MEMBERS iterations or more: made 2 here, so that it does on a test-sized mesh.
    # The buffers handed to the family filled with NaN on arrival (they are free by then): the check
    # takes its scratch from them, passes every member, and the family equals flow() and gives the same
    # bits on 1 and 2 threads.
    from shapeflow.flow import compiled, family_paths

    mesh = cube_sphere(16, mix=0.3)
    monkeypatch.setattr(compiled, "RESIDUAL_MEMBERS", 2)
    handed, taken = [], []

    def spare(self, buffers):
        for b in buffers:
            b[:] = np.nan
        handed.extend(buffers)
        self.buffers = buffers

    class Spy(compiled.Spare):
        def take(self, rows, width):
            taken.append(super().take(rows, width))
            return taken[-1]

    monkeypatch.setattr(family_paths.MemberSink, "spare", spare)
    monkeypatch.setattr(compiled, "Spare", Spy)
    one, report = family_on(1, mesh, FIGURE1, axes=axes, return_report=True)
    assert report.fallback_members == [] and len(handed) == sum(axes) and len(taken) == 1
    assert any(np.shares_memory(taken[0], b) for b in handed)           # (the check's scratch in the block)
    assert np.array_equal(one, family_on(2, mesh, FIGURE1, axes=axes))
    with accel.use(kernels="off"):
        refs = {lam: sf.flow(mesh, lam, axes=axes).vertices for lam in FIGURE1}
    worst = max(float(np.abs(one[m] - refs[lam]).max()) for m, lam in enumerate(FIGURE1))
    assert worst <= TOL * mesh.diagonal, worst
