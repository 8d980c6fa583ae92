"""The flow kernel family's family kernels: the members' true residuals (``member_residuals``) and the
members formed from a low-rank solve (``add_members``), NumPy reference and compiled, against dense
NumPy arithmetic written out here; and the family's use of them (the low-rank path, a corrupted
factor found by the check)."""

from __future__ import annotations

import importlib
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from meshgen import cube_sphere

import shapeflow as sf
from shapeflow import accel
from shapeflow.errors import SolverWarning

paths = importlib.import_module("shapeflow.flow.family_paths")
KERNELS = ["off", "force"]


def _spd(n: int, seed: int):
    """A sparse symmetric positive definite matrix (int32 CSR, as the flow's systems) with a few
    duplicate-free off-diagonal entries per row."""
    rng = np.random.default_rng(seed)
    i = rng.integers(0, n, 4 * n)
    j = rng.integers(0, n, 4 * n)
    keep = i != j
    W = sp.coo_matrix((rng.uniform(0.1, 1.0, keep.sum()), (i[keep], j[keep])), shape=(n, n)).tocsr()
    W = W + W.T
    A = (sp.diags(np.asarray(W.sum(axis=1)).ravel() + rng.uniform(0.5, 2.0, n)) - W).tocsr()
    A.sum_duplicates()
    A.indices = A.indices.astype(np.int32)
    A.indptr = A.indptr.astype(np.int32)
    return A


@pytest.mark.parametrize("kernels", KERNELS)
@pytest.mark.parametrize("cols", [[0, 1, 2], [0, 2], [1]])
def test_member_residuals_are_the_dense_ones(kernels, cols):
    """‖(A + δ I) y − b‖ and ‖y‖ with y = ±(x − base) / scale, for 21 members (more than one block of
    the compiled kernel), against a dense product; a non-finite position gives a non-finite residual; the
    same with spare buffers of garbage for the scratch (the compiled kernel takes the first with room)."""
    rng = np.random.default_rng(5)
    n, k = 300, 23
    A = _spd(n, 1)
    cols = np.array(cols)
    out = rng.normal(size=(k, n, 3))
    base = rng.normal(size=(n, 3))
    inv_scale = rng.uniform(0.5, 2.0, n)
    members = np.array([m for m in range(k) if m not in (3, 11)])
    signs = np.where(rng.random(members.size) < 0.5, -1.0, 1.0)
    deltas = rng.uniform(0.0, 3.0, members.size)
    R0 = rng.normal(size=(cols.size, n))
    out[members[4], 17, cols[-1]] = np.nan
    spare = [np.full(10, np.nan), np.full(3 * 16 * n + 7, np.nan)]     # (too small; room for the scratch)
    with accel.use(kernels=kernels):
        kern = accel.kernels("flow", n)
        res, ynorm = kern.member_residuals(A, R0, out, base, inv_scale, cols, members, signs, deltas)
        res2, ynorm2 = kern.member_residuals(A, R0, out, base, inv_scale, cols, members, signs, deltas, spare)
    assert np.array_equal(res, res2, equal_nan=True) and np.array_equal(ynorm, ynorm2, equal_nan=True)
    assert np.isnan(spare[0]).all()
    if kernels == "force" and accel.numba_available():
        assert not np.isnan(spare[1][:3 * 16 * n]).all()                # the compiled check's scratch
    D = A.toarray()
    for q, m in enumerate(members):
        for t, j in enumerate(cols):
            y = signs[q] * (out[m, :, j] - base[:, j]) * inv_scale
            want = np.linalg.norm(D @ y + deltas[q] * y - R0[t])
            if q == 4 and t == cols.size - 1:
                assert not np.isfinite(res[q, t])
                continue
            assert res[q, t] == pytest.approx(want, rel=1e-12)
            assert ynorm[q, t] == pytest.approx(np.linalg.norm(y), rel=1e-13)


@pytest.mark.skipif(not accel.numba_available(), reason="the compiled kernels need numba")
def test_member_residuals_give_the_same_bits_on_any_number_of_threads():
    """The compiled check shares the rows out between threads by blocks whose sums are added in block
    order (20,000 rows: ten blocks)."""
    rng = np.random.default_rng(9)
    n, k = 20000, 18
    A = _spd(n, 3)
    out = rng.normal(size=(k, n, 3))
    base = rng.normal(size=(n, 3))
    args = (A, rng.normal(size=(3, n)), out, base, rng.uniform(0.5, 2.0, n), np.arange(3), np.arange(k),
            np.where(rng.random(k) < 0.5, -1.0, 1.0), rng.uniform(0.0, 3.0, k))
    got = {}
    for threads in (1, 2):
        with accel.use(kernels="force", threads=threads):
            check = accel.heavy(accel.kernels("flow", n).member_residuals)      # (heavy: the threads applied)
            got[threads] = check(*args)
    assert np.array_equal(got[1][0], got[2][0]) and np.array_equal(got[1][1], got[2][1])


@pytest.mark.parametrize("kernels", KERNELS)
@pytest.mark.parametrize("cols", [[0, 1, 2], [2]])
def test_add_members_writes_base_plus_the_low_rank_product(kernels, cols):
    """out[m] = base, plus ±(L_t W_t)[q] in column t, for members sharing shifts (one shift twice, one
    never), ranks differing by column, more vertices than one block; untouched members stay as they
    were; a shift whose values are not finite is reported."""
    rng = np.random.default_rng(8)
    n, k, nm = 9000, 7, 10
    cols = np.array(cols)
    out = rng.normal(size=(nm, n, 3))
    before = out.copy()
    base = rng.normal(size=(n, 3))
    ranks = [4, 2, 5][:cols.size]
    lefts = [rng.normal(size=(k, r)) for r in ranks]
    Ws = [rng.normal(size=(n, r)) for r in ranks]      # vertex-major
    Ws[0][4321, 1] = np.inf                       # shift q's values at vertex 4321 are inf where L[q, 1] ≠ 0
    lefts[0][2, 1] = 0.0                          # ... except shift 2: 0 · inf is NaN there too
    members = np.array([0, 2, 3, 5, 6, 8, 9])
    shift_of = np.array([0, 1, 1, 2, 4, 5, 6])     # shift 3 has no member, shift 1 two
    signs = np.array([1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0])
    with accel.use(kernels=kernels), np.errstate(invalid="ignore"):
        kern = accel.kernels("flow", n)
        finite = kern.add_members(out, base, cols, members, shift_of, signs, lefts, Ws, k)
    assert not finite[[0, 1, 2, 4, 5, 6]].any() and finite[3]
    for p, m in enumerate(members):
        want = base.copy()
        for t, j in enumerate(cols):
            with np.errstate(invalid="ignore"):
                want[:, j] += signs[p] * (lefts[t][shift_of[p]] @ Ws[t].T)
        ok = np.isfinite(want)
        assert np.array_equal(np.isfinite(out[m]), ok)
        assert np.allclose(out[m][ok], want[ok], rtol=1e-13, atol=1e-13)
    untouched = np.setdiff1d(np.arange(nm), members)
    assert np.array_equal(out[untouched], before[untouched])


@pytest.mark.parametrize("kernels", KERNELS)
def test_add_members_takes_pieces_side_by_side(kernels):
    """Ws[t] as a tuple of pieces (the factor's columns side by side): the same members as the one
    array ``np.hstack(pieces)``."""
    rng = np.random.default_rng(9)
    n, k = 9000, 5
    cols = np.array([0, 2])
    base = rng.normal(size=(n, 3))
    pieces = [tuple(rng.normal(size=(n, r)) for r in (3, 3, 3)), tuple(rng.normal(size=(n, r)) for r in (2, 2))]
    lefts = [rng.normal(size=(k, 9)), rng.normal(size=(k, 4))]
    members, shift_of, signs = np.arange(k), np.arange(k), np.array([1.0, -1.0, 1.0, 1.0, -1.0])
    out = np.zeros((k, n, 3))
    with accel.use(kernels=kernels):
        kern = accel.kernels("flow", n)
        finite = kern.add_members(out, base, cols, members, shift_of, signs, lefts, pieces, k)
    assert finite.all()
    for p in range(k):
        want = base.copy()
        for t, j in enumerate(cols):
            want[:, j] += signs[p] * (np.hstack(pieces[t]) @ lefts[t][p])
        assert np.allclose(out[p], want, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("kernels", KERNELS)
def test_family_takes_the_low_rank_path_and_its_check_finds_a_wrong_factor(kernels, monkeypatch):
    """48 members on a 3,000-vertex mesh: the members come from the low-rank factors (``factors``,
    not rows) and equal flow() within 1e-7 of the diagonal; a factor row of one shift scaled by
    1 + 1e-5 is found by the true-residual check, that member redone as flow() and named."""
    mesh = cube_sphere(22, mix=0.3, seed=3)
    lams = np.arange(0.0, -240.0, -5.0)
    real = paths.MemberSink.factors
    corrupt = {"on": False}
    seen = []

    def factors(self, lefts, Ws):
        seen.append(len(lefts))
        if corrupt["on"]:
            lefts = [L.copy() for L in lefts]
            for L in lefts:
                L[5] *= 1.0 + 1e-5          # shift 5 (ascending σ): the member of λ = −210
        return real(self, lefts, Ws)

    monkeypatch.setattr(paths.MemberSink, "factors", factors)
    with accel.use(kernels=kernels):
        with warnings.catch_warnings():
            warnings.simplefilter("error", SolverWarning)
            shapes, report = sf.family(mesh, lams, return_report=True)
        assert seen and report.path == "multishift" and report.fallback_members == []
        worst = max(float(np.abs(shapes[m] - sf.flow(mesh, float(lam)).vertices).max())
                    for m, lam in enumerate(lams) if m % 7 == 0 or m == lams.size - 1)
        assert worst <= 1e-7 * mesh.diagonal
        corrupt["on"] = True
        with pytest.warns(SolverWarning, match=r"1 member\(s\).*λ = -210"):
            bad, report = sf.family(mesh, lams, return_report=True)
        assert report.fallback_members == [42]
        assert np.abs(bad[42] - sf.flow(mesh, -210.0).vertices).max() <= 1e-7 * mesh.diagonal


@pytest.mark.parametrize("kernels", KERNELS)
def test_members_outside_the_shared_solve_survive_the_result_used_as_its_scratch(kernels, monkeypatch):
    """The shared solve forms its factor in the result's memory (``MemberSink.scratch``, filled with NaN
    here before it is handed out): the members it does not write — λ = 0 (the input), a λ below
    1/1.8e308 (solved as flow()) — are written afterwards, and the members checked equal flow() at their
    λ (the first members: those whose memory the factor took)."""
    mesh = cube_sphere(22, mix=0.3, seed=3)
    lams = np.r_[0.0, -1e-310, np.arange(-5.0, -240.0, -5.0)[:20], 0.0, np.arange(-5.0, -240.0, -5.0)[20:]]
    real = paths.MemberSink.scratch
    used = []

    def garbage(self, size):
        buf = real(self, size)
        if buf is not None:
            buf[:] = np.nan
            used.append(size)
        return buf

    monkeypatch.setattr(paths.MemberSink, "scratch", garbage)
    check, handed = paths.check_members, []

    def spy(*args):
        handed.append(args[-1])
        return check(*args)

    monkeypatch.setattr(paths, "check_members", spy)
    with accel.use(kernels=kernels):
        fam = sf.family(mesh, lams)
        assert used, "the shared solve did not use the result as its scratch"
        assert len(handed) == 1 and len(handed[0]) == 3      # the seed's block, three slabs, for the check
        V = mesh.vertices
        for m in np.flatnonzero(lams == 0.0):
            assert np.array_equal(fam[m], V)
        for m in (1, 3, lams.size - 2):
            want = sf.flow(mesh, float(lams[m])).vertices
            assert np.abs(fam[m] - want).max() <= 1e-7 * np.ptp(V, axis=0).max(), m
