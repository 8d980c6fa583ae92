"""The compiled kernels (``fast`` extra) against their NumPy twins.

Every test builds the same thing twice — kernels forced on for any size and
kernels off — and compares.  Integer structures must be identical; floating
results equal to rounding (the CG's parallel sums differ in order).
"""

from __future__ import annotations

import meshgen
import numpy as np
import pytest
from conftest import shared_mesh_paths

import shapeflow as sf
from shapeflow import accel as kernels
from shapeflow.operators.cotan import assemble as _assemble
from shapeflow.operators.pattern import OperatorPattern as _Structure

pytestmark = pytest.mark.skipif(not kernels.available(), reason="numba (the 'fast' extra) not installed")


@pytest.fixture
def forced():
    """Kernels for every size inside the test."""
    with kernels.use(min_size=0):
        yield


def _degenerate_grid() -> sf.Mesh:
    """Mixed grid with a zero-length edge, a flat corner triangle and a sub-1e-5 face (locks, bad corners)."""
    m = meshgen.grid(9, 7, jitter=0.1, seed=4, mix=0.4, z=lambda x, y: 0.1 * np.sin(x) * y)
    V = m.vertices.copy()
    V[12] = V[13]                          # zero-length edge
    V[30] = 0.5 * (V[29] + V[31])          # flat triangles around vertex 30
    V[45] = V[44] + 1e-7 * (V[45] - V[44])  # tiny elements (Blender's absolute rule)
    return sf.Mesh.from_csr(V, m.face_sizes, m.face_indices)


def _meshes():
    out = [
        ("degenerate_grid", _degenerate_grid()),
        ("grid_quads", meshgen.grid(9, 7, jitter=0.2, seed=1)),
        ("grid_mixed", meshgen.grid(8, 8, jitter=0.1, seed=2, mix=0.5)),
        ("cube_sphere_mixed", meshgen.cube_sphere(6, mix=0.4, seed=3)),
        ("icosphere", meshgen.icosphere(2)),
        ("ngon_disk", meshgen.ngon_disk(7, 3)),
    ]
    for p in shared_mesh_paths()[:6]:
        out.append((p.name, sf.load(p)))
    return out


MESHES = _meshes()


def _fresh(m: sf.Mesh) -> sf.Mesh:
    return sf.Mesh.from_csr(m.vertices, m.face_sizes, m.face_indices)


@pytest.mark.parametrize("name,mesh", MESHES, ids=[n for n, _ in MESHES])
def test_edges_identical(name, mesh, forced):
    a = _fresh(mesh).topology
    with kernels.enabled(False):
        b = _fresh(mesh).topology
        ref = b._edge_data
    got = a._edge_data
    for x, y in zip(got, ref):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("scheme", ["tqlbo", "blender"])
@pytest.mark.parametrize("name,mesh", MESHES, ids=[n for n, _ in MESHES])
def test_structure_and_assembly_match(name, mesh, scheme, forced):
    t = _fresh(mesh).topology
    fast = _Structure(t, scheme)
    with kernels.enabled(False):
        slow = _Structure(t, scheme)
    np.testing.assert_array_equal(fast.pairs, slow.pairs)
    np.testing.assert_array_equal(fast.skip_pair, slow.skip_pair)
    np.testing.assert_array_equal(fast.corner_w, slow.corner_w)
    np.testing.assert_array_equal(fast.corner_aw, slow.corner_aw)
    np.testing.assert_array_equal(fast.indptr, slow.indptr)
    np.testing.assert_array_equal(fast.indices, slow.indices)
    # positions may differ only among duplicate entries (a chord shared by two faces)
    rng = np.random.default_rng(0)
    d, o = rng.standard_normal(t.n_vertices), rng.standard_normal(fast.pairs.shape[0])
    A, B = fast.matrix(d, o), slow.matrix(d, o)
    assert abs(A - B).max() < 1e-14
    for thresholds in ("relative", "blender"):
        m1 = _fresh(mesh)
        r_fast = _assemble(m1, scheme, thresholds)
        with kernels.enabled(False):
            m2 = _fresh(mesh)
            r_slow = _assemble(m2, scheme, thresholds)
        for x, y in zip(r_fast[1:4], r_slow[1:4]):   # pair weights, degree, ring area
            np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-13 * np.abs(y).max())
        np.testing.assert_array_equal(r_fast[4], r_slow[4])
        assert r_fast[5] == r_slow[5]
        if name == "degenerate_grid":   # the locking rules were exercised
            assert r_slow[4].sum() >= 4 and r_slow[5] >= 1


def test_repeated_vertex_found(forced):
    with pytest.raises(sf.MeshError, match="face 1 repeats a vertex"):
        sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3, 2]])


def _broken_layouts(mix=0.3):
    """(name, sizes, indices) on a 30 x 30 grid of quads (``mix``: the share split into triangles),
    each broken in one or two faces."""
    g = meshgen.grid(30, 30, mix=mix, seed=2)
    S, I, O = g.face_sizes.copy(), g.face_indices.copy(), g.topology.face_offsets
    m = S.size
    out = [("valid", S, I)]
    for f in (0, m // 2, m - 1):            # first, middle and last face: the search is split by threads
        J = I.copy()
        J[O[f] + 1] = J[O[f]]
        out.append((f"repeat {f}", S, J))
        J = I.copy()
        J[O[f] + 2] = g.n_vertices
        out.append((f"too large {f}", S, J))
        J = I.copy()
        J[O[f]] = -1
        out.append((f"negative {f}", S, J))
    # a two-corner face early and an out-of-range vertex earlier still: the size message comes first
    S2 = np.concatenate([S[:5], [2], S[5:]])
    J = np.concatenate([I[:O[5]], [0, 1], I[O[5]:]])
    J[0] = g.n_vertices + 7
    out.append(("short face after a bad vertex", S2, J))
    return g.vertices, out


@pytest.mark.parametrize("mix", [0.3, 1.0], ids=["mixed", "triangles"])
def test_validation_same_verdict_and_message(mix):
    """The compiled one-pass check (fast path; triangles have their own branch) changes no verdict
    and no message."""
    V, cases = _broken_layouts(mix)

    def verdict(S, I):
        try:
            sf.Mesh.from_csr(V, S, I)
        except sf.MeshError as e:
            return str(e)
        return None

    for name, S, I in cases:
        with kernels.enabled(False):
            slow = verdict(S, I)
        with kernels.use(min_size=0):
            fast = verdict(S, I)
        assert (slow is None) == (name == "valid"), name
        assert fast == slow, name
    from shapeflow.mesh import compiled as NK
    for name, S, I in cases:
        offsets = np.concatenate([[0], np.cumsum(S)])
        f = NK.first_bad_face(I.astype(np.int64), offsets, V.shape[0])
        assert (f < 0) == (name == "valid"), name
        if name.split()[-1].isdigit():
            assert f == int(name.split()[-1]), name


@pytest.mark.parametrize("lam", [1.0, -20.0])
@pytest.mark.parametrize("name,mesh", MESHES[:4], ids=[n for n, _ in MESHES[:4]])
def test_flow_same_result(name, mesh, lam, forced):
    fast = sf.flow(_fresh(mesh), lam, lam_border=0.5, iterations=2)
    with kernels.enabled(False):
        slow = sf.flow(_fresh(mesh), lam, lam_border=0.5, iterations=2)
    diag = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
    assert np.abs(fast.vertices - slow.vertices).max() < 1e-9 * diag
    assert fast.report.cg_iterations == pytest.approx(slow.report.cg_iterations, abs=1)


@pytest.mark.parametrize("name,mesh", MESHES[:4], ids=[n for n, _ in MESHES[:4]])
def test_interior_system_identical(name, mesh, forced):
    """Matrix, diagonal and the coupling terms (free row, fixed column, weight) of the
    interior system: the compiled pass gives the NumPy arrays, in the same order."""
    w = np.random.default_rng(1).uniform(0.0, 1.0, mesh.n_vertices)
    w[::5] = 0.0                                   # weight-0 vertices: held rows with free neighbours
    fs = sf.FlowSolver(_fresh(mesh), weights=w)
    op = fs.operator()                             # one operator for both (assembly is compared above)
    out = []
    for on in (True, False):
        with kernels.enabled(on):
            isys = fs.systems.interior(op, -4.0, 1, [])
            out.append((isys.A.toarray(), isys.solver.minv, isys.coupling, isys.c))
    (A1, m1, c1, d1), (A0, m0, c0, d0) = out
    assert np.array_equal(A1, A0) and np.array_equal(m1, m0) and np.array_equal(d1, d0)
    assert c0[0].size > 0
    for x, y in zip(c1, c0):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("lam", [2.0, -3.0])
def test_fixed_steps_same_result(lam, forced):
    """The compiled Clenshaw step against the NumPy one (open mesh: held rim, coupling term)."""
    mesh = meshgen.grid(12, 10, jitter=0.2, seed=9, mix=0.3, z=lambda x, y: 0.2 * np.sin(x) * np.cos(y))
    fast = sf.flow(_fresh(mesh), lam, iterations=6, solver="chebyshev")
    with kernels.enabled(False):
        slow = sf.flow(_fresh(mesh), lam, iterations=6, solver="chebyshev")
    assert fast.report.solver == slow.report.solver == "chebyshev"
    disp = np.abs(slow.vertices - mesh.vertices).max()
    assert disp > 0 and np.abs(fast.vertices - slow.vertices).max() < 1e-10 * disp


def test_permuted_pattern_is_the_permuted_matrix(forced):
    """``_Structure.locality``: the pattern in RCM order, with each entry's source, is P A Pᵀ
    (duplicates kept), and the fixed-operator expansion in that order gives the same steps."""
    mesh = meshgen.grid(14, 11, jitter=0.2, seed=3, mix=0.4, z=lambda x, y: 0.1 * x * y)
    st = _Structure(mesh.topology, "tqlbo")
    perm, inv, ptr, idx, src = st.locality()
    assert np.array_equal(np.sort(perm), np.arange(mesh.n_vertices)) and np.array_equal(inv[perm], np.arange(perm.size))
    data = np.random.default_rng(1).standard_normal(st.indices.size)
    A = st.matrix_from_data(data).toarray()              # duplicates summed by toarray
    import scipy.sparse as sp
    Ap = sp.csr_matrix((data[src], idx, ptr), shape=A.shape)
    assert np.all(np.diff(idx.astype(np.int64))[np.diff(np.repeat(np.arange(perm.size), np.diff(ptr))) == 0] >= 0)
    np.testing.assert_allclose(Ap.toarray(), A[np.ix_(perm, perm)], rtol=0, atol=1e-14)
    assert sorted(src.tolist()) == list(range(st.indices.size))     # every entry once
    # the expansion's products in the permuted order: same result as without
    m = sf.Mesh.from_csr(mesh.vertices, mesh.face_sizes, mesh.face_indices)
    a = sf.flow(m, 2.0, iterations=6, solver="chebyshev")
    st2 = sf.operators.operator_pattern(m, "tqlbo")
    assert st2._locality["numba"] is not None            # the permuted path ran
    st2._locality.clear()
    real = st2.locality
    st2.locality = lambda: None                          # the unpermuted path
    b = sf.flow(m, 2.0, iterations=6, solver="chebyshev")
    st2.locality = real
    disp = np.abs(b.vertices - mesh.vertices).max()
    assert a.report.solver == b.report.solver == "chebyshev"
    assert disp > 0 and np.abs(a.vertices - b.vertices).max() < 1e-12 * disp


def test_cg_kernel_columns(forced):
    """1, 2 and 3 columns; zero columns stay zero; same answer as the NumPy CG."""
    from shapeflow.linalg import SPDSolver

    m = meshgen.cube_sphere(8)
    W = sf.cotan_weights(m).W
    d = np.asarray(W.sum(axis=1)).ravel()
    import scipy.sparse as sp

    A = (sp.diags(2.0 * d) - W).tocsr()
    A.indices = A.indices.astype(np.int32)
    A.indptr = A.indptr.astype(np.int32)
    rng = np.random.default_rng(4)
    for k in (1, 2, 3):
        B = rng.standard_normal((A.shape[0], k)) if k > 1 else rng.standard_normal(A.shape[0])
        x = SPDSolver(A, "cg", rtol=1e-12).solve(B)
        with kernels.enabled(False):
            y = SPDSolver(A, "cg", rtol=1e-12).solve(B)
        assert x.shape == B.shape
        np.testing.assert_allclose(x, y, atol=1e-9 * np.abs(y).max())
        np.testing.assert_allclose(A @ x, B, atol=1e-8 * np.abs(B).max())
        scratch = np.ascontiguousarray(B.copy())            # B as the residual's storage: same answer
        z = SPDSolver(A, "cg", rtol=1e-12).solve(scratch, overwrite_b=True)
        np.testing.assert_array_equal(z, x)
        if k == 3:
            assert not np.array_equal(scratch, B)          # it was used (holds the last residual)


def test_small_meshes_do_not_use_kernels():
    size = kernels.current().min_size
    if kernels.current().kernels == "force":   # SHAPEFLOW_KERNELS=force: every size by definition
        assert kernels.kernels("mesh", 1).backend == "numba"
    else:
        assert kernels.kernels("mesh", size - 1).backend == "numpy"
    assert kernels.kernels("mesh", size).backend == "numba"
    with kernels.enabled(False):
        assert kernels.kernels("mesh", 10**9).backend == "numpy"


def test_results_do_not_depend_on_the_thread_count(monkeypatch):
    """threads="auto" picks the thread count from the machine's load at each call: the compiled
    Jacobi CG sums in fixed blocks (on one thread in its sequential build, on two in parallel),
    the Gauss–Seidel CG is sequential, and the split dab solve does the same arithmetic on one
    thread, so the same input gives the same bits however busy the machine is."""
    from shapeflow.linalg import spd

    m = meshgen.grid(40, 30, jitter=0.1, seed=2, mix=0.3, z=lambda x, y: 0.1 * np.sin(x) * y)
    out = {}
    for t in (1, 2):
        with kernels.use(kernels="force", threads=t):
            a = sf.flow(m, -20.0, solver="cg", iterations=2)
            monkeypatch.setattr(spd, "DEFAULT_PRECONDITIONER", "jacobi")
            j = sf.flow(m, -20.0, solver="cg", iterations=2)
            monkeypatch.setattr(spd, "DEFAULT_PRECONDITIONER", "auto")
            b = sf.Brush(m, lam=-30.0, radius=0.35 * m.diagonal)
            b.dab(m.vertices[m.n_vertices // 2])
            out[t] = (a.vertices, b.vertices, b.last.solver, j.vertices)
    np.testing.assert_array_equal(out[1][0], out[2][0])
    np.testing.assert_array_equal(out[1][1], out[2][1])
    assert out[1][2] == out[2][2]
    np.testing.assert_array_equal(out[1][3], out[2][3])
    assert np.abs(out[1][3] - out[1][0]).max() > 0     # the two preconditioners did run


@pytest.mark.parametrize("name,mesh", [MESHES[i] for i in (2, 4)], ids=[MESHES[i][0] for i in (2, 4)])
def test_pair_pattern_both_paths_against_the_numpy_pattern(name, mesh):
    """Strictly sorted pairs (a mesh's edges) take the kernel's no-sort path, other pairs the general
    one; both give the NumPy pattern and every entry's position."""
    from shapeflow.operators import compiled
    from shapeflow.operators.pattern import csr_pattern

    n = mesh.n_vertices
    edges = _fresh(mesh).topology.edges.astype(np.int32)
    rng = np.random.default_rng(5)
    shuffled = edges[rng.permutation(edges.shape[0])]
    assert compiled.strictly_sorted(edges) and not compiled.strictly_sorted(shuffled)
    for pairs in (edges, shuffled):
        P = pairs.shape[0]
        rows = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
        cols = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
        indptr, indices, entry_at = csr_pattern(rows, cols, n)
        pos = np.empty_like(entry_at)
        pos[entry_at] = np.arange(entry_at.size)
        got = compiled.pair_pattern(pairs, n)
        for x, y in zip(got, (indptr, indices, pos[:P], pos[P:2 * P], pos[2 * P:])):
            np.testing.assert_array_equal(x, y)


def test_max_row_distance_compiled_and_numpy(forced):
    from shapeflow.flow.solver import max_row_distance

    rng = np.random.default_rng(3)
    A = rng.standard_normal((10_000, 3))
    B = A + 1e-3 * rng.standard_normal((10_000, 3))
    B[7777] += [0.3, -0.4, 1.2]                               # the farthest row: 1.3 away
    fast = max_row_distance(A, B)
    with kernels.enabled(False):
        slow = max_row_distance(A, B)
    ref = float(np.sqrt(((A - B) ** 2).sum(axis=1)).max())
    assert abs(fast - ref) <= 1e-15 * ref and abs(slow - ref) <= 1e-15 * ref and abs(ref - 1.3) < 0.01
    B[5] = np.nan
    assert np.isnan(max_row_distance(A, B))
