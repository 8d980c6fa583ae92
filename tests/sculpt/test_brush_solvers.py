"""The brush's small-system solvers (issue 8): LAPACK's banded Cholesky with its padding, and the split
solver (two banded halves on two threads, a dense separator), each against a dense solve."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from meshgen import grid

import shapeflow as sf


@pytest.mark.parametrize("band", [30, 56, 60, 64, 65, 80])
def test_banded_solve_with_and_without_padding(band, monkeypatch):
    """Bands 56-64 go to LAPACK padded to 65 (its blocked code); the solution is the same system's."""
    from shapeflow.linalg import banded as B
    from shapeflow.linalg.local import LocalSolver

    rng = np.random.default_rng(band)
    k = 400
    # a random SPD band matrix: symmetric off-diagonals within `band`, dominant diagonal
    ri, ci = [], []
    for i in range(k):
        for j in rng.choice(np.arange(i + 1, min(k, i + band + 1)), size=min(4, k - i - 1), replace=False) \
                if i < k - 1 else []:
            ri.append(i)
            ci.append(int(j))
    ri.append(0)
    ci.append(band)                                   # the band is exactly `band`
    ri, ci = np.array(ri), np.array(ci)
    v = -rng.uniform(0.1, 1.0, ri.size)
    R, C, Vv = np.concatenate([ri, ci]), np.concatenate([ci, ri]), np.concatenate([v, v])
    o = np.lexsort((C, R))
    R, C, Vv = R[o], C[o], Vv[o]
    diag = np.bincount(R, np.abs(Vv), minlength=k) + 1.0
    rhs = rng.standard_normal((k, 3))
    A = np.zeros((k, k))
    A[R, C] = Vv
    A[np.arange(k), np.arange(k)] = diag
    expected = np.linalg.solve(A, rhs)

    seen = []
    real = B.banded_cholesky
    monkeypatch.setattr(sys.modules["shapeflow.linalg.local"], "banded_cholesky",
                        lambda *a: seen.append(a[-1]) or real(*a))
    solver = LocalSolver("banded")
    X, used, bw = solver.solve(k, R, C, Vv, diag, rhs)
    assert used == "banded" and bw == band                  # the report keeps the true band
    assert seen == [65 if 56 <= band <= 64 else band]
    np.testing.assert_allclose(X, expected, rtol=1e-10, atol=1e-12)
    # the band storage is reused: a second, smaller solve on the same brush (stale values in
    # the buffer must not leak into it) and the first one again
    half = (R < k // 2) & (C < k // 2)
    X2, _, _ = solver.solve(k // 2, R[half], C[half], Vv[half], diag[:k // 2], rhs[:k // 2])
    A2 = np.zeros((k // 2, k // 2))
    A2[R[half], C[half]] = Vv[half]
    A2[np.arange(k // 2), np.arange(k // 2)] = diag[:k // 2]
    np.testing.assert_allclose(X2, np.linalg.solve(A2, rhs[:k // 2]), rtol=1e-10, atol=1e-12)
    X3, _, _ = solver.solve(k, R, C, Vv, diag, rhs)
    np.testing.assert_array_equal(X3, X)


# --- the split solver: two banded halves on two threads, a dense separator ------------------

def _split_ready():
    from shapeflow.linalg.blas import split_routines

    return sf.accel.available() and split_routines() is not None


requires_split = pytest.mark.skipif(not _split_ready(), reason="needs numba and SciPy's OpenBLAS LAPACK pointers")


def _grid_system(w, h, seed, eight=True, shuffle=True):
    """An SPD system on a w x h grid graph (4- or 8-neighbour), rows grouped in increasing
    order, unknowns numbered at random: (k, ri, ci, vi, diag, rhs, dense A)."""
    rng = np.random.default_rng(seed)
    k = w * h
    idx = np.arange(k).reshape(h, w)
    steps = [(0, 1), (1, 0)] + ([(1, 1), (1, -1)] if eight else [])
    a, b = [], []
    for dy, dx in steps:
        src = idx[max(0, -dy):h - max(0, dy), max(0, -dx):w - max(0, dx)]
        dst = idx[max(0, dy):h + min(0, dy) or None, max(0, dx):w + min(0, dx) or None]
        a.append(src.ravel())
        b.append(dst.ravel())
    a, b = np.concatenate(a), np.concatenate(b)
    p = rng.permutation(k) if shuffle else np.arange(k)
    a, b = p[a], p[b]
    v = -rng.uniform(0.2, 1.0, a.size)
    R, C, V = np.concatenate([a, b]), np.concatenate([b, a]), np.concatenate([v, v])
    o = np.lexsort((rng.random(R.size), R))          # grouped by row, neighbours in any order
    R, C, V = R[o], C[o], V[o]
    diag = np.bincount(R, -V, minlength=k) + rng.uniform(1e-4, 1e-2, k)   # a Laplacian + a small mass
    rhs = rng.standard_normal((k, 3))
    A = np.zeros((k, k))
    A[R, C] = V
    A[np.arange(k), np.arange(k)] = diag
    return k, R, C, V, diag, rhs, A


@requires_split
@pytest.mark.parametrize("w, h, eight", [(40, 30, True), (36, 36, False), (60, 25, True), (70, 40, True)])
def test_split_solve_matches_a_dense_solve(w, h, eight, monkeypatch):
    from shapeflow.linalg import banded as B
    from shapeflow.linalg import compiled_split as K
    from shapeflow.linalg.local import LocalSolver

    k, R, C, V, diag, rhs, A = _grid_system(w, h, seed=w * h, eight=eight)
    seen = []
    real = K.split_solve
    # record perm and dims of every call
    monkeypatch.setattr(K, "split_solve", lambda *a: seen.append((a[-5].copy(), a[-3].copy())) or real(*a))
    solver = LocalSolver("auto")
    X, used, bw = solver.solve(k, R, C, V, diag, rhs)
    assert used == "split"
    np.testing.assert_allclose(X, np.linalg.solve(A, rhs), rtol=1e-9, atol=1e-11)
    # the order, checked from its definition
    (perm, dims), = seen
    nA, nB, nS, kdA, kdB, tA, tB = (int(x) for x in dims)
    assert nA + nB + nS == k and np.array_equal(np.sort(perm), np.arange(k))
    pos = np.empty(k, np.int64)
    pos[perm] = np.arange(k)
    i, j = pos[R], pos[C]
    part = np.where(i < nA, 0, np.where(i < nA + nB, 1, 2)), np.where(j < nA, 0, np.where(j < nA + nB, 1, 2))
    assert not ((part[0] == 0) & (part[1] == 1)).any()          # the halves are not coupled
    inA, inB = (part[0] == 0) & (part[1] == 0), (part[0] == 1) & (part[1] == 1)
    true_a, true_b = np.abs(i - j)[inA].max(), np.abs(i - j)[inB].max()
    assert bw == max(true_a, true_b)
    for true, kd in ((true_a, kdA), (true_b, kdB)):   # LAPACK sees the band, padded as BLOCKED_BAND says
        assert kd == (B.BLOCKED_BAND[1] if B.BLOCKED_BAND[0] <= true < B.BLOCKED_BAND[1] else true)
    toS = part[1] == 2
    assert (i[toS & (part[0] == 0)] >= nA - tA).all() and (i[toS & (part[0] == 1)] >= nA + nB - tB).all()
    assert 0 < tA <= nA and 0 < tB <= nB
    # halves balanced around the median level
    assert min(nA, nB) >= k // 5


@requires_split
def test_split_solver_falls_back_where_it_does_not_apply():
    import numba

    from shapeflow.linalg.local import LocalSolver

    k, R, C, V, diag, rhs, A = _grid_system(40, 30, seed=5)
    solver = LocalSolver("auto")
    ref = np.linalg.solve(A, rhs)
    # components: the largest is split, the others join the smaller half
    kk, Rk, Ck, Vk, dk, rk, Ak = _grid_system(12, 9, seed=8)
    R2, C2 = np.concatenate([R, Rk + k]), np.concatenate([C, Ck + k])
    V2, d2 = np.concatenate([V, Vk]), np.concatenate([diag, dk, [2.0]])   # + an isolated unknown
    rhs2 = np.vstack([rhs, rk, [[1.0, -2.0, 4.0]]])
    X, used, _ = solver.solve(k + kk + 1, R2, C2, V2, d2, rhs2)
    assert used == "split"
    np.testing.assert_allclose(X, np.vstack([ref, np.linalg.solve(Ak, rk), [[0.5, -1.0, 2.0]]]),
                               rtol=1e-9, atol=1e-11)
    # no balanced cut (a star: the median unknown's level holds all but two): not split
    ks = 1200
    Rs = np.concatenate([np.zeros(ks - 1, np.int64), np.arange(1, ks)])
    Cs = np.concatenate([np.arange(1, ks), np.zeros(ks - 1, np.int64)])
    o = np.argsort(Rs, kind="stable")
    Rs, Cs = Rs[o], Cs[o]
    Vs = -np.ones(Rs.size)
    ds = np.full(ks, 2.0)
    ds[0] = ks + 1.0
    As = np.diag(ds)
    As[Rs, Cs] = Vs
    X, used, _ = solver.solve(ks, Rs, Cs, Vs, ds, rhs[:ks])
    assert used != "split"
    np.testing.assert_allclose(X, np.linalg.solve(As, rhs[:ks]), rtol=1e-9, atol=1e-11)
    # not positive definite: LU takes over, the answer is still the system's
    bad = diag.copy()
    bad[::7] = -5.0
    A_bad = A.copy()
    A_bad[np.arange(k), np.arange(k)] = bad
    X, used, _ = solver.solve(k, R, C, V, bad, rhs)
    assert used in ("lu", "cholesky")
    np.testing.assert_allclose(A_bad @ X, rhs, rtol=1e-8, atol=1e-8)
    # one thread: the same split, the halves one after the other, the same bits
    X2, used2, _ = solver.solve(k, R, C, V, diag, rhs)
    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        X1, used1, _ = solver.solve(k, R, C, V, diag, rhs)
    finally:
        numba.set_num_threads(old)
    assert used1 == used2 == "split"
    np.testing.assert_array_equal(X1, X2)
    np.testing.assert_allclose(X1, ref, rtol=1e-9, atol=1e-11)
    # an explicit solver="banded" never splits; small systems do not either
    assert LocalSolver("banded").solve(k, R, C, V, diag, rhs)[1] == "banded"
    ks, Rs, Cs, Vs, ds, rs, As = _grid_system(20, 20, seed=6)
    assert solver.solve(ks, Rs, Cs, Vs, ds, rs)[1] == "banded"


@requires_split
def test_split_dabs_equal_one_band_dabs():
    """Dabs of ~1,500 unknowns on a bumpy grid: the split solver and the one-band solver agree."""
    mesh = grid(60, 60, jitter=0.2, mix=0.3, seed=3, z=lambda x, y: 0.3 * np.sin(0.5 * x) * np.cos(0.4 * y))
    c = mesh.vertices[np.argmin(np.linalg.norm(mesh.vertices - mesh.vertices.mean(0), axis=1))]
    a = sf.Brush(mesh, lam=-30.0, radius=0.38 * mesh.diagonal)
    b = sf.Brush(mesh, lam=-30.0, radius=0.38 * mesh.diagonal, solver="banded")
    for shift in (0.0, 0.1, -0.1):
        p = c + shift * mesh.diagonal
        a.dab(p)
        b.dab(p)
        assert a.last.solver == "split" and b.last.solver == "banded"
        assert a.last.indices.size >= 1000
        np.testing.assert_array_equal(a.last.indices, b.last.indices)
        assert np.abs(a.last.positions - b.last.positions).max() <= 1e-10 * mesh.diagonal


def test_a_fallback_from_the_split_solver_is_reported(monkeypatch):
    import shapeflow.linalg.local as B
    from shapeflow.linalg.blas import FALLBACKS

    if not sf.accel.available():
        pytest.skip("the split solver needs numba (the 'fast' extra)")
    from shapeflow.linalg import compiled_split

    monkeypatch.setattr(compiled_split, "split_routines", lambda: None)   # as on a SciPy without OpenBLAS's setter
    monkeypatch.setitem(FALLBACKS, "split", "the split solver is unavailable here")
    mesh = sf.load_example("spot")
    brush = sf.Brush(mesh, lam=-20.0, radius=0.9)
    brush.dab(mesh.vertices.mean(axis=0))
    assert brush.last.n_inside >= B.SPLIT_MIN
    assert brush.last.solver == "banded" and brush.last.notes == ["the split solver is unavailable here"]
