"""Robustness (issue 10): degenerate meshes, bad input everywhere, property tests, reader fuzzing."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import MESHES, requires_shared, run_cli
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from meshgen import grid, icosphere, random_rotation
from mutation import mutate, numpy_draw

import shapeflow as sf
from shapeflow.errors import MeshError, ParameterError

# ----------------------------------------------------------------------------
# random hybrid meshes
# ----------------------------------------------------------------------------

def hybrid_mesh(nx, ny, seed, split, merge, zscale, closed_cap):
    """A bumpy grid of quads; some split into triangles, some pairs merged into hexagons."""
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float), indexing="ij")
    V = np.c_[xs.ravel() + 0.2 * rng.uniform(-1, 1, nx * ny), ys.ravel() + 0.2 * rng.uniform(-1, 1, nx * ny),
              zscale * rng.standard_normal(nx * ny)]
    faces = []
    used = set()
    for i in range(nx - 1):
        for j in range(ny - 1):
            if (i, j) in used:
                continue
            a, b, c, d = i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1
            r = rng.random()
            if r < merge and i + 2 < nx and (i + 1, j) not in used:
                e, f = (i + 2) * ny + j, (i + 2) * ny + j + 1
                faces.append([a, b, e, f, c, d])          # hexagon over two quads
                used.add((i + 1, j))
            elif r < merge + split:
                faces += [[a, b, c], [a, c, d]]
            else:
                faces.append([a, b, c, d])
    if closed_cap:  # add an apex fan over the border: a closed "tent"
        apex = len(V)
        V = np.vstack([V, [(nx - 1) / 2, (ny - 1) / 2, -3.0]])
        border = ([i * ny for i in range(nx)] + [(nx - 1) * ny + j for j in range(1, ny)]
                  + [i * ny + ny - 1 for i in range(nx - 2, -1, -1)] + [j for j in range(ny - 2, 0, -1)])
        for k in range(len(border)):
            faces.append([border[(k + 1) % len(border)], border[k], apex])
    return sf.Mesh(V, faces)


meshes = st.builds(
    hybrid_mesh,
    nx=st.integers(3, 7), ny=st.integers(3, 7), seed=st.integers(0, 10_000),
    split=st.floats(0, 0.6), merge=st.floats(0, 0.4), zscale=st.floats(0, 0.5), closed_cap=st.booleans())

flow_options = st.fixed_dictionaries({
    "lam": st.floats(-500, 500, allow_nan=False),
    "lam_border": st.floats(-20, 20, allow_nan=False),
    "iterations": st.integers(0, 3),
    "normalized": st.booleans(),
    "preserve_volume": st.booleans(),
    "compat": st.sampled_from([None, "blender"]),
    "axes": st.sampled_from(["xyz", "xy", "z", ""]),
})

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(mesh=meshes, opts=flow_options, wseed=st.integers(0, 1000), scale=st.integers(-6, 6))
def test_flow_properties(mesh, opts, wseed, scale):
    mesh = mesh.with_vertices(mesh.vertices * 10.0 ** scale)
    rng = np.random.default_rng(wseed)
    w = rng.uniform(0, 1, mesh.n_vertices)
    w[rng.random(mesh.n_vertices) < 0.2] = 0.0
    lam = opts.pop("lam")
    out = sf.flow(mesh, lam, weights=w, **opts)
    V = out.vertices
    assert np.isfinite(V).all()
    assert out.n_faces == mesh.n_faces
    # sane bound: nothing flies off beyond a few hundred model sizes
    assert np.abs(V - mesh.vertices.mean(axis=0)).max() <= 1e3 * max(mesh.diagonal, 1e-300)
    if not opts["preserve_volume"]:
        assert np.array_equal(V[w == 0], mesh.vertices[w == 0])
        # disabled axes never change
        for k, c in enumerate("xyz"):
            if c not in opts["axes"]:
                assert np.array_equal(V[:, k], mesh.vertices[:, k])
    if (lam == 0 and opts["lam_border"] == 0) or opts["iterations"] == 0 or not opts["axes"]:
        assert np.array_equal(V, mesh.vertices)


@SETTINGS
@given(mesh=meshes, lam=st.floats(-300, 300, allow_nan=False), lam_b=st.floats(-5, 5, allow_nan=False),
       rseed=st.integers(0, 1000), iterations=st.integers(1, 2), preserve_volume=st.booleans())
def test_flow_rigid_motion_equivariance(mesh, lam, lam_b, rseed, iterations, preserve_volume):
    if preserve_volume:
        # volume preservation rescales by (V_before / V_after)^(1/3): on a near-flat open surface the
        # enclosed volume is of the order of the rounding of the moved copy's coordinates, so the
        # two runs may not agree to 1e-7; such surfaces are left to the degenerate-geometry tests
        area = float(np.linalg.norm(sf.geometry.face_vector_areas(mesh), axis=1).sum())
        assume(abs(sf.geometry.signed_volume(mesh)) > 1e-6 * area * mesh.diagonal)
    R = random_rotation(rseed)
    t = np.random.default_rng(rseed).uniform(-10, 10, 3)
    moved = mesh.with_vertices(mesh.vertices @ R.T + t)
    kw = dict(lam_border=lam_b, iterations=iterations, preserve_volume=preserve_volume, rtol=1e-12)
    a = sf.flow(mesh, lam, **kw)
    b = sf.flow(moved, lam, **kw)
    scale = max(np.abs(a.vertices).max(), mesh.diagonal)
    np.testing.assert_allclose(b.vertices, a.vertices @ R.T + t, atol=1e-7 * scale)


@pytest.mark.parametrize("scale", [1e-6, 1e-3, 1.0, 1e3, 1e6])
def test_normalised_flow_is_scale_equivariant(scale):
    m = hybrid_mesh(6, 5, 3, 0.3, 0.2, 0.3, True)
    a = sf.flow(m, -40.0, lam_border=2.0, iterations=2, preserve_volume=True, rtol=1e-12)
    b = sf.flow(m.with_vertices(m.vertices * scale), -40.0, lam_border=2.0, iterations=2,
                preserve_volume=True, rtol=1e-12)
    np.testing.assert_allclose(b.vertices, a.vertices * scale, rtol=1e-8, atol=1e-9 * scale)
    assert b.report.locked == 0


# ----------------------------------------------------------------------------
# degenerate geometry: each has a documented rule and a report
# ----------------------------------------------------------------------------

def _check(out, mesh):
    assert np.isfinite(out.vertices).all()
    assert np.abs(out.vertices).max() <= 1e3 * (np.abs(mesh.vertices).max() + mesh.diagonal)


def test_zero_length_edge_and_zero_area_face_are_locked():
    m = grid(6, jitter=0.1, seed=2, z=lambda x, y: 0.1 * x * y)
    V = m.vertices.copy()
    V[8] = V[9]                              # zero-length edge
    V[14] = 0.5 * (V[13] + V[15])            # straight corner: flat corner triangles around 14
    bad = m.with_vertices(V)
    out = sf.flow(bad, -50.0, iterations=2, lam_border=1.0)
    _check(out, bad)
    assert {8, 9, 14} <= set(out.report.locked_vertices.tolist())
    assert np.array_equal(out.vertices[[8, 9, 14]], V[[8, 9, 14]])
    assert out.report.degenerate_triangles > 0


def test_needle_face_is_excluded():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-12, 0], [0.5, 1, 0.2], [0.5, -1, 0.2]], float)
    m = sf.Mesh(V, [[0, 1, 2], [0, 2, 3], [2, 1, 3], [1, 0, 4]])
    out = sf.flow(m, -10.0, lam_border=1.0)
    _check(out, m)
    assert out.report.degenerate_triangles >= 1


def test_coincident_unconnected_vertices_are_fine():
    a = icosphere(1)
    b = a.with_vertices(a.vertices)  # a second, separate copy at the same place
    both = sf.concatenate([a, b])
    out = sf.flow(both, -20.0, preserve_volume=True)
    _check(out, both)
    np.testing.assert_allclose(out.vertices[:a.n_vertices], out.vertices[a.n_vertices:], atol=1e-12)


def test_nonmanifold_edges_and_vertices_and_isolated_vertices():
    # three quads on one edge, a bow-tie vertex, and an unreferenced vertex
    V = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0.1], [-1, 1, 0.1],
                  [0, 0, 1], [0, 1, 1], [2, 2, 0], [2, 1, 0.3], [3, 3, 3]], float)
    faces = [[0, 2, 3, 1], [1, 5, 4, 0], [0, 1, 7, 6], [3, 8, 9]]
    m = sf.Mesh(V, faces)
    d = m.diagnostics()
    assert d.nonmanifold_edges == 1 and d.unreferenced_vertices == 1
    out = sf.flow(m, -5.0, lam_border=1.0, iterations=2)
    _check(out, m)
    assert np.array_equal(out.vertices[10], V[10])   # isolated vertex: no neighbours, never moves
    assert any("non-manifold" in n for n in out.report.notes)


def test_inconsistent_orientation_is_reported_and_finite():
    m = icosphere(2)
    faces = m.faces_as_lists()
    faces[0] = faces[0][::-1]
    flipped = sf.Mesh(m.vertices, faces)
    out = sf.flow(flipped, -10.0, preserve_volume=True)
    _check(out, flipped)
    assert any("orientation" in n for n in out.report.notes)
    # cotangent weights do not depend on orientation: same flow without volume preservation
    np.testing.assert_allclose(sf.flow(flipped, -10.0).vertices, sf.flow(m, -10.0).vertices, atol=1e-12)


def test_mesh_without_faces_and_empty_mesh():
    m = sf.Mesh(np.zeros((3, 3)), [])
    out = sf.flow(m, -5.0)
    assert np.array_equal(out.vertices, m.vertices)
    e = sf.Mesh(np.zeros((0, 3)), [])
    assert sf.flow(e, 1.0).n_vertices == 0


# ----------------------------------------------------------------------------
# bad input to every public function: a ValueError subclass naming the problem
# ----------------------------------------------------------------------------

def _mesh():
    return icosphere(1)


BAD_CALLS = [
    ("vertices wrong shape", lambda: sf.Mesh(np.zeros((4, 2)), [[0, 1, 2]]), MeshError, r"\(n, 3\)"),
    ("vertices NaN", lambda: sf.Mesh([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]), MeshError, "vertex 0"),
    ("vertices strings", lambda: sf.Mesh([["a", "b", "c"]] * 3, [[0, 1, 2]]), MeshError, "numbers"),
    ("index out of range", lambda: sf.Mesh(np.zeros((3, 3)), [[0, 1, 5]]), MeshError, "vertex 5"),
    ("negative index", lambda: sf.Mesh(np.zeros((3, 3)), [[0, 1, -1]]), MeshError, "-1"),
    ("face too small", lambda: sf.Mesh(np.zeros((3, 3)), [[0, 1]]), MeshError, "at least 3"),
    ("repeated vertex", lambda: sf.Mesh(np.zeros((4, 3)), [[0, 1, 1, 2]]), MeshError, "repeats"),
    ("float faces", lambda: sf.Mesh(np.zeros((3, 3)), np.array([[0, 1, 2.5]])), MeshError, "integers"),
    ("csr mismatch", lambda: sf.Mesh.from_csr(np.zeros((3, 3)), [3, 3], [0, 1, 2]), MeshError, "add up"),
    ("weights length", lambda: _mesh().with_weights(np.ones(3)), MeshError, "one value per vertex"),
    ("weights range", lambda: _mesh().with_weights(np.full(_mesh().n_vertices, 2.0)), MeshError, r"\[0, 1\]"),
    ("lam inf", lambda: sf.flow(_mesh(), np.inf), ParameterError, "finite"),
    ("lam_border nan", lambda: sf.flow(_mesh(), 1.0, lam_border=np.nan), ParameterError, "finite"),
    ("iterations negative", lambda: sf.flow(_mesh(), 1.0, iterations=-2), ParameterError, ">= 0"),
    ("iterations float", lambda: sf.flow(_mesh(), 1.0, iterations=2.0), ParameterError, "integer"),
    ("flow weights nan", lambda: sf.flow(_mesh(), 1.0, weights=np.full(_mesh().n_vertices, np.nan)),
     ParameterError, "vertex 0"),
    ("not a mesh", lambda: sf.flow(np.zeros((3, 3)), 1.0), ParameterError, "Mesh"),
    ("scheme", lambda: sf.laplacian(_mesh(), scheme="cubic"), ParameterError, "scheme"),
    ("area kind", lambda: sf.vertex_areas(_mesh(), "voronoi"), ParameterError, "area kind"),
    ("curvature area", lambda: sf.mean_curvature(_mesh(), area="voronoi"), ParameterError, "area kind"),
    ("subdivide levels", lambda: sf.subdivide(_mesh(), -1), ParameterError, "levels"),
    ("subdivide scheme", lambda: sf.subdivide(_mesh(), 1, scheme="loop"), ParameterError, "scheme"),
    ("strength negative", lambda: sf.smooth(_mesh(), -1.0), ParameterError, "strength"),
]


@pytest.mark.parametrize("name,call,exc,match", BAD_CALLS, ids=[c[0] for c in BAD_CALLS])
def test_bad_input_raises_named_value_error(name, call, exc, match):
    with pytest.raises(exc, match=match):
        call()
    assert issubclass(exc, ValueError)


def test_bad_files(tmp_path):
    with pytest.raises(MeshError, match="missing.obj"):
        sf.load(tmp_path / "missing.obj")
    p = tmp_path / "mesh.fbx"
    p.write_text("Kaydara FBX")
    with pytest.raises(MeshError, match="fbx"):
        sf.load(p)
    junk = tmp_path / "junk.ply"
    junk.write_bytes(os.urandom(4096))
    with pytest.raises(MeshError, match="junk.ply"):
        sf.load(junk)
    with pytest.raises(MeshError, match=r"w.txt: line 2: .*outside \[0, 1\]"):
        sf.load_weights(_write_weights(tmp_path, [0.5, 2.0]), 2)


def _write_weights(tmp_path, values):
    p = tmp_path / "w.txt"
    p.write_text("\n".join(map(str, values)))
    return p


# ----------------------------------------------------------------------------
# the command line: one line, exit 2, nothing lost
# ----------------------------------------------------------------------------

def test_cli_refuses_to_overwrite_input_and_leaves_no_partial_file(tmp_path, capsys):
    src = tmp_path / "in.obj"
    sf.save(src, icosphere(1))
    before = src.read_bytes()
    code, _, err = run_cli(["enhance", str(src), str(src), "--strength", "5"], capsys)
    assert code == 2 and "--force" in err and len(err.strip().splitlines()) == 1
    assert src.read_bytes() == before
    code, _, _ = run_cli(["enhance", str(src), str(src), "--strength", "5", "--force", "-q"], capsys)
    assert code == 0 and src.read_bytes() != before
    # a failing run (bad weights file) writes nothing
    out = tmp_path / "out.ply"
    bad_w = _write_weights(tmp_path, [0.5] * 3)
    code, _, err = run_cli(["enhance", str(src), str(out), "--strength", "5", "--weights", str(bad_w)], capsys)
    assert code == 2 and not out.exists() and len(err.strip().splitlines()) == 1
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".") or "tmp" in p.name]


@pytest.mark.parametrize("args,match", [
    (["flow", "{src}", "{out}", "--lambda", "nan"], "finite"),
    (["flow", "{src}", "{out}", "--lambda", "1", "--iterations", "-3"], ">= 0"),
    (["enhance", "{src}", "{out}", "--strength", "-1"], "strength"),
    (["enhance", "{src}", "{out}", "--strength", "1", "--axes", "xq"], "axes"),
    (["enhance", "{src}", "{out}", "--strength", "1", "--weights", "nosuch"], "neither a file nor"),
    (["enhance", "{missing}", "{out}", "--strength", "1"], "missing"),
    (["enhance", "{src}", "{tmp}/out.fbx", "--strength", "1"], "fbx"),
    (["info", "{junk}"], "junk"),
    (["subdivide", "{src}", "{out}", "--levels", "-1"], "levels"),
])
def test_cli_errors_are_one_line_exit_2(tmp_path, capsys, args, match):
    src = tmp_path / "in.obj"
    sf.save(src, icosphere(1))
    junk = tmp_path / "junk.off"
    junk.write_bytes(b"OFF\n3 1 0\n0 0 0\n1 1\n\x00\xff")
    fmt = dict(src=src, out=tmp_path / "out.obj", missing=tmp_path / "missing.obj", tmp=tmp_path, junk=junk)
    code, _, err = run_cli([a.format(**fmt) for a in args], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err
    assert match in err
    assert not (tmp_path / "out.obj").exists()


def test_cli_subprocess_has_no_traceback(tmp_path):
    r = subprocess.run([sys.executable, "-m", "shapeflow", "flow", str(tmp_path / "nope.obj"), str(tmp_path / "o.obj"),
                        "--lambda", "1"], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


# ----------------------------------------------------------------------------
# reader fuzzing: >= 10,000 mutated real files, only MeshError, never a hang
# ----------------------------------------------------------------------------

@requires_shared
def test_fuzz_readers_with_mutated_real_files(tmp_path):
    seeds = []
    for name in ("spot_control_hybrid.obj", "blub_control_hybrid.obj", "penguin_control_hybrid.obj",
                 "pawn_cage_quad_open.obj"):
        m = sf.load(MESHES / name)
        m = m.with_weights(np.linspace(0, 1, m.n_vertices))
        for ext, binary in ((".obj", None), (".off", None), (".ply", False), (".ply", True)):
            p = tmp_path / f"seed{ext}"
            sf.save(p, m, binary=binary)
            seeds.append((ext, p.read_bytes()))
        seeds.append((".obj", (MESHES / name).read_bytes()))
    draw = numpy_draw(np.random.default_rng(20261121))
    n_cases = int(os.environ.get("SHAPEFLOW_FUZZ_CASES", "10000"))
    loaded = 0
    for i in range(n_cases):
        ext, data = seeds[i % len(seeds)]
        p = tmp_path / f"case{ext}"
        p.write_bytes(mutate(data, draw))
        try:
            m = sf.load(p)
        except MeshError as exc:
            assert str(exc).startswith(str(p)), exc
        else:
            loaded += 1
            assert np.isfinite(m.vertices).all()
            assert m.face_indices.size == 0 or m.face_indices.max() < m.n_vertices
    assert 0 < loaded < n_cases  # the mutations produce both valid and invalid files


@pytest.mark.parametrize("scale", [1.0, 1e6])
def test_subnormal_lambda_moves_nothing_without_overflow(scale):
    # found by hypothesis: λ_b = 2.2e-311 made the row scale C overflow
    import warnings

    m = hybrid_mesh(4, 4, 1, 0.3, 0.0, 0.2, False)
    m = m.with_vertices(m.vertices * scale)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = sf.flow(m, 1e-310, lam_border=-2.2e-311, normalized=False)
    np.testing.assert_array_equal(out.vertices, m.vertices)
