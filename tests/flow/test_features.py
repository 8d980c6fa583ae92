"""Feature-aware flow (sharp edges): detection, the curve rule, and what it keeps exactly.

Expected values come from the shapes' construction (tests/flow/feature_shapes.py: which vertices lie
on a flat face, a straight edge, a corner), from normals computed here, and, for the curve rule,
from the closed-form solution of the step on a regular polygon.  Flatness and straightness are
checked to 1e-9 of the bounding-box diagonal (best-fit plane or line by SVD); corners must not move.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.errors import ParameterError
from shapeflow.geometry.features import angle_sharp_edges, dihedral_angles, edge_ids

_spec = importlib.util.spec_from_file_location("feature_shapes", Path(__file__).with_name("feature_shapes.py"))
fs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fs)

EXACT = 1e-9   # × diagonal


plane_dev, line_dev = fs.plane_dev, fs.line_dev


SHAPES = {
    "nut": lambda: fs.nut(),
    "box_mixed": lambda: fs.box(split=0.3, hexagons=2),
    "prism3": lambda: fs.prism(3),
    "l_bracket": lambda: fs.l_bracket(split=0.2, seed=3),
}

OPTIONS = {
    "plain": {},
    "blender": {"compat": "blender"},
    "area": {"normalized": False},
    "weights": {"weights": "w"},
    "fixed3": {"iterations": 3},
    "recompute3": {"iterations": 3, "update": "recompute"},
    "lu": {"solver": "lu"},
}


def _opts(mesh, opts):
    out = dict(opts)
    if out.get("weights") == "w":
        w = np.random.default_rng(7).uniform(0.2, 1.0, mesh.n_vertices)
        w[::11] = 0.0
        out["weights"] = w
    return out


def check_features(mesh, info, out, *, corners=True):
    D = mesh.diagonal
    V = out.vertices
    flat = max(plane_dev(V[g]) for g in info["caps"] + info["sides"])
    assert flat <= EXACT * D, flat / D
    straight = max(line_dev(V[g]) for g in info["edges"])
    assert straight <= EXACT * D, straight / D
    if corners:
        assert np.abs(V[info["corners"]] - mesh.vertices[info["corners"]]).max() <= EXACT * D


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("opt", OPTIONS)
@pytest.mark.parametrize("lam", [10.0, -25.0])
def test_flat_faces_straight_edges_and_corners_stay(shape, opt, lam):
    mesh, info = SHAPES[shape]()
    opts = _opts(mesh, OPTIONS[opt])
    out = sf.flow(mesh, lam, feature_angle=30.0, **opts)
    check_features(mesh, info, out)
    smooth = info["hole"] if info["hole"].size else info.get("smooth", np.zeros(0, np.int64))
    if smooth.size:   # the round hole, the fillet: they still smooth or enhance, by a clear amount
        moved = np.linalg.norm(out.vertices[smooth] - mesh.vertices[smooth], axis=1).max()
        assert moved > 5e-3 * mesh.diagonal, moved / mesh.diagonal
    if opt == "weights":
        zero = opts["weights"] == 0
        assert np.array_equal(out.vertices[zero], mesh.vertices[zero])


@pytest.mark.parametrize("lam", [8.0, -15.0])
def test_volume_preservation_keeps_faces_flat(lam):
    mesh, info = fs.nut()
    out = sf.flow(mesh, lam, feature_angle=30.0, preserve_volume=True)
    check_features(mesh, info, out, corners=False)      # a global rescale moves the corners too
    vol = sf.geometry.measures.signed_volume
    assert abs(vol(out) - vol(mesh)) <= 1e-9 * abs(vol(mesh))


def test_the_hole_rim_follows_the_closed_form_curve_step():
    # the rim of the hole is a regular N-gon of curve vertices (its neighbours on the curve are
    # rim vertices): with L_c = I − D⁻¹W and equal weights it is an eigenvector, eigenvalue
    # μ = 1 − cos(2π/N): one step scales its radius by 1/(1 + |λ|μ) (then reflected for λ < 0)
    corners = [[np.cos(k * np.pi / 3), np.sin(k * np.pi / 3)] for k in range(6)]
    outer = fs.polyline(corners, 4)
    a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    mesh, info = fs.extrusion(outer, corners, inner=0.45 * np.c_[np.cos(a), np.sin(a)], height=0.6)
    V = mesh.vertices
    rim = info["hole"][np.abs(V[info["hole"], 2] - V[:, 2].max()) < 1e-12]
    N = rim.size
    mu = 1.0 - np.cos(2 * np.pi / N)
    for lam in (6.0, -6.0):
        out = sf.flow(mesh, lam, feature_angle=30.0, solver="lu").vertices
        r = np.hypot(out[rim, 0], out[rim, 1])
        s = 1.0 / (1.0 + abs(lam) * mu)
        expect = 0.45 * (s if lam > 0 else 2.0 - s)
        np.testing.assert_allclose(r, expect, rtol=1e-12)
        np.testing.assert_allclose(out[rim, 2], V[rim, 2], atol=1e-15)
        # along the rim: the angles do not change (no sliding)
        np.testing.assert_allclose(np.arctan2(out[rim, 1], out[rim, 0]), np.arctan2(V[rim, 1], V[rim, 0]),
                                   atol=1e-12)


def test_unevenly_spaced_straight_edges_do_not_slide():
    # the curve weights 1/length have linear precision: a straight feature line stays exactly
    # where it is, however its vertices are spaced (uniform weights would even them out)
    corners = [[0, 0], [2, 0], [2, 1], [0, 1]]
    t = np.array([0.0, 0.05, 0.3, 0.35, 0.8])
    outer = np.concatenate([np.asarray(corners[k]) + t[:, None] * (np.asarray(corners[(k + 1) % 4])
                                                                 - np.asarray(corners[k])) for k in range(4)])
    mesh, info = fs.extrusion(outer, corners, center=(1.0, 0.5), layers=4)
    out = sf.flow(mesh, -30.0, feature_angle=45.0, solver="lu").vertices
    lines = np.concatenate(info["edges"])
    assert np.abs(out[lines] - mesh.vertices[lines]).max() <= 1e-13


@pytest.mark.parametrize("shape", ["nut", "box_mixed"])
@pytest.mark.parametrize("opts", [{}, {"iterations": 3}, {"compat": "blender", "preserve_volume": True},
                                  {"normalized": False, "iterations": 2, "update": "recompute"}])
def test_without_sharp_edges_the_flow_is_bit_identical(shape, opts):
    mesh, _ = SHAPES[shape]()
    lam = -12.0
    plain = sf.flow(mesh, lam, **opts).vertices
    assert np.array_equal(sf.flow(mesh, lam, feature_angle=None, sharp_edges=None, **opts).vertices, plain)
    # the feature machinery with nothing sharp: not one bit changes
    assert np.array_equal(sf.flow(mesh, lam, feature_angle=180.0, **opts).vertices, plain)
    assert np.array_equal(sf.flow(mesh, lam, sharp_edges=np.zeros((0, 2), int), **opts).vertices, plain)


def test_smooth_surfaces_flow_as_without_features():
    sphere = sf.subdivide(sf.Mesh([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                                  [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                                   [1, 5, 7, 3]]), 3)
    assert not angle_sharp_edges(sphere, 30.0).any()
    for lam in (5.0, -20.0):
        assert np.array_equal(sf.flow(sphere, lam, feature_angle=30.0).vertices, sf.flow(sphere, lam).vertices)


# --- detection ---------------------------------------------------------------------------------

def test_dihedral_angles_of_a_hexagonal_prism():
    mesh, info = fs.prism(6, per_side=2, layers=2)
    ang = dihedral_angles(mesh)
    e = mesh.topology.edges
    V = mesh.vertices
    xy = V[:, :2]
    corner = np.zeros(len(V), bool)
    for k in range(6):
        corner |= np.linalg.norm(xy - [np.cos(k * np.pi / 3), np.sin(k * np.pi / 3)], axis=1) < 1e-12
    # on the hexagon: the distance to the centre along the side's normal is cos 30°
    th = np.arctan2(V[:, 1], V[:, 0])
    on_hex = np.abs(np.hypot(V[:, 0], V[:, 1]) * np.cos(np.mod(th, np.pi / 3) - np.pi / 6) - np.cos(np.pi / 6)) < 1e-9
    vertical_corner = corner[e[:, 0]] & corner[e[:, 1]]
    rim = (V[e[:, 0], 2] == V[e[:, 1], 2]) & np.isin(V[e[:, 0], 2], [0.0, 1.0]) & on_hex[e[:, 0]] & on_hex[e[:, 1]]
    np.testing.assert_allclose(ang[vertical_corner], 60.0, atol=1e-9)
    np.testing.assert_allclose(ang[rim], 90.0, atol=1e-9)
    np.testing.assert_allclose(ang[~vertical_corner & ~rim], 0.0, atol=1e-6)
    assert vertical_corner.sum() == 6 * 2 and rim.sum() == 2 * 6 * 2
    assert angle_sharp_edges(mesh, 59.0).sum() == 36
    assert angle_sharp_edges(mesh, 61.0).sum() == 24
    assert angle_sharp_edges(mesh, 90.5).sum() == 0


@pytest.mark.parametrize("shape", ["nut", "box_mixed", "prism3", "l_bracket"])
def test_compiled_detection_equals_numpy(shape):
    # the compiled pass over the corners and the NumPy twin decide every edge alike, exact
    # thresholds included (the nut's vertical edges bend by 60°, its rims by 90°)
    mesh, info = SHAPES[shape]()
    bent = mesh.with_vertices(mesh.vertices + 0.01 * np.sin(7 * mesh.vertices[:, [1, 2, 0]]))
    top = set(info["caps"][1].tolist())
    faces = [f for f in mesh.faces_as_lists() if not set(f) <= top]
    opened = sf.Mesh(mesh.vertices, faces)                               # boundary edges
    flat = mesh.vertices.copy()
    flat[faces[0]] = flat[faces[0][0]] + 1e-300 * np.arange(len(faces[0]))[:, None]   # a face of zero area
    fin = sf.Mesh(mesh.vertices, mesh.faces_as_lists() + [faces[0][:2] + [int(info["corners"][0])]])
    for m in (mesh, bent, opened, fin, sf.Mesh(flat, mesh.faces_as_lists())):
        for a in (0.0, 5.0, 30.0, 60.0, 90.0, 120.0, 179.0):
            with sf.accel.use(kernels="force"):
                fast = angle_sharp_edges(m, a)
            with sf.accel.use(kernels="off"):
                slow = angle_sharp_edges(m, a)
            assert np.array_equal(fast, slow), (a, int((fast != slow).sum()))


def test_boundary_edges_are_never_sharp_and_fins_always_are():
    # an open box (no top): its rim is boundary, never sharp by angle
    mesh, info = fs.box(per_side=2, layers=2)
    top = info["caps"][1]
    keep = [f for f in mesh.faces_as_lists() if not set(f) <= set(top)]
    open_box = sf.Mesh(mesh.vertices, keep)
    t = open_box.topology
    sharp = angle_sharp_edges(open_box, 10.0)
    assert not sharp[t.boundary_edge_mask].any()
    # three quads on one edge: non-manifold, sharp at any angle
    fin = sf.Mesh([[0, 0, 0], [0, 0, 1], [1, 0, 0], [1, 0, 1], [-1, 0, 0], [-1, 0, 1], [0, 1, 0], [0, 1, 1]],
                  [[0, 2, 3, 1], [1, 5, 4, 0], [0, 6, 7, 1]])
    s = angle_sharp_edges(fin, 179.0)
    assert s.sum() == 1 and fin.topology.edges[s].tolist() == [[0, 1]]


def test_orientation_does_not_make_an_edge_sharp():
    # two coplanar quads, the second wound the other way: their normals are opposite, the surface flat
    m = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]], [[0, 1, 2, 3], [1, 2, 5, 4]])
    assert np.nanmax(dihedral_angles(m)) < 1e-9
    assert not angle_sharp_edges(m, 1.0).any()


def test_sharp_edges_are_checked():
    mesh, _ = fs.box(per_side=2, layers=1)
    e = mesh.topology.edges
    good = e[:3]
    assert np.array_equal(np.sort(edge_ids(mesh, good[:, ::-1])), np.sort(edge_ids(mesh, good)))
    bad_rows = [
        (np.r_[good, [[0, 0]]], "row 3 \\(0, 0\\) is not an edge"),
        (np.r_[good, [[0, mesh.n_vertices]]], "row 3 .* outside"),
        (np.r_[good, [[0.5, 1]]], "row 3 .* not a pair of vertex indices"),
        (np.zeros((2, 3)), "\\(k, 2\\)"),
        ([["a", "b"]], "real numbers"),
    ]
    for E, msg in bad_rows:
        with pytest.raises(ParameterError, match="sharp_edges.*" + msg):
            sf.flow(mesh, 1.0, sharp_edges=E)
    with pytest.raises(ParameterError, match="sharp_edges"):
        sf.flow(mesh, 1.0, sharp_edges="file")
    for a in (-1.0, 181.0, float("nan"), "30", True):
        with pytest.raises(ParameterError, match="feature_angle"):
            sf.flow(mesh, 1.0, feature_angle=a)


def test_given_edges_and_angle_union():
    mesh, info = fs.nut()
    by_angle = angle_sharp_edges(mesh, 30.0)
    pairs = mesh.topology.edges[by_angle]
    a = sf.flow(mesh, -10.0, feature_angle=30.0).vertices
    b = sf.flow(mesh, -10.0, sharp_edges=pairs).vertices
    c = sf.flow(mesh, -10.0, sharp_edges=pairs[: len(pairs) // 2], feature_angle=30.0).vertices
    assert np.array_equal(a, b) and np.array_equal(a, c)


def test_report_counts_curves_ends_and_corners():
    # box of 4 segments per cap side, 3 wall layers: 2 caps × 16 outline edges + 4 vertical lines × 3
    mesh, info = fs.box(per_side=4, layers=3)
    rep = sf.flow(mesh, 1.0, feature_angle=45.0).report
    assert rep.sharp_edges == 2 * 16 + 4 * 3
    assert rep.feature_fixed == 8                     # the corners
    assert rep.curve_vertices == 2 * 12 + 4 * 2        # outline points between corners, vertical line points
    assert "8 curve ends and corners stay" in rep.summary()
    assert sf.flow(mesh, 1.0).report.sharp_edges == 0


def test_a_curve_end_stays():
    # one sharp polyline ending inside a smooth region (a crease drawn on a sphere-like surface)
    m = sf.subdivide(sf.Mesh([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                             [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                              [1, 5, 7, 3]]), 2)
    e = m.topology.edges
    V = m.vertices
    on = (np.abs(V[e[:, 0], 1]) < 1e-12) & (np.abs(V[e[:, 1], 1]) < 1e-12) & (V[e[:, 0], 2] > 0.2) \
        & (V[e[:, 1], 2] > 0.2)
    chain = e[on]
    ends = np.flatnonzero(np.bincount(chain.ravel(), minlength=m.n_vertices) == 1)
    middle = np.flatnonzero(np.bincount(chain.ravel(), minlength=m.n_vertices) == 2)
    assert ends.size == 2 and middle.size >= 1
    out = sf.flow(m, 20.0, sharp_edges=chain)
    assert np.array_equal(out.vertices[ends], V[ends])
    assert np.abs(out.vertices[middle] - V[middle]).max() > 1e-3
    # the chain lies in the plane y = 0: its vertices stay in it
    assert np.abs(out.vertices[middle, 1]).max() <= 1e-15
    assert out.report.curve_vertices == middle.size and out.report.feature_fixed == 2


@pytest.mark.parametrize("lam_border", [0.0, 2.0, -1.0])
def test_open_mesh_with_the_boundary_factor(lam_border):
    mesh, info = fs.box(per_side=3, layers=3)
    top = set(info["caps"][1].tolist())
    open_box = sf.Mesh(mesh.vertices, [f for f in mesh.faces_as_lists() if not set(f) <= top])
    rim = open_box.topology.boundary_vertices
    out = sf.flow(open_box, -10.0, lam_border=lam_border, feature_angle=30.0, solver="lu").vertices
    D = open_box.diagonal
    bottom = info["caps"][0]
    assert plane_dev(out[bottom]) <= EXACT * D
    low_corners = np.intersect1d(info["corners"], bottom)
    assert np.array_equal(out[low_corners], open_box.vertices[low_corners])
    moved_rim = np.abs(out[rim] - open_box.vertices[rim]).max()
    if lam_border == 0.0:
        assert moved_rim == 0.0
        for side in info["sides"]:        # walls bounded by sharp edges and the fixed rim stay flat
            assert plane_dev(out[side]) <= EXACT * D
    else:
        assert moved_rim > 1e-3 * D


def test_flow_solver_keeps_the_classification():
    mesh, info = fs.nut()
    solver = sf.FlowSolver(mesh, feature_angle=30.0)
    a = solver.run(-10.0)
    curves = solver.systems.curves
    b = solver.run(5.0, iterations=2, update="recompute")
    assert solver.systems.curves is curves
    assert np.array_equal(a.vertices, sf.flow(mesh, -10.0, feature_angle=30.0).vertices)
    assert np.array_equal(b.vertices, sf.flow(mesh, 5.0, feature_angle=30.0, iterations=2,
                                              update="recompute").vertices)
    check_features(mesh, info, b)


def test_smoothing_groups_and_crease_tags_from_obj(tmp_path):
    mesh, info = fs.box(per_side=2, layers=2)
    n = mesh.n_vertices
    sharp = angle_sharp_edges(mesh, 45.0)
    normals = np.round(sf.geometry.measures.face_vector_areas(mesh), 9)
    _, group = np.unique(np.sign(normals), axis=0, return_inverse=True)   # one group per face of the box
    order = np.argsort(group.ravel(), kind="stable")
    lines = ["v %r %r %r" % tuple(p) for p in mesh.vertices.tolist()]
    faces = mesh.faces_as_lists()
    last = None
    for f in order:
        if group.ravel()[f] != last:
            last = group.ravel()[f]
            lines.append(f"s {last + 1}")
        lines.append("f " + " ".join(str(i + 1) for i in faces[f]))
    p = tmp_path / "groups.obj"
    p.write_text("\n".join(lines) + "\n")
    m = sf.load(p)
    ref = sf.flow(mesh, -10.0, feature_angle=45.0)
    got = sf.flow(m, -10.0, sharp_edges="mesh")
    # the faces were written in another order: the same shape, vertex for vertex (to rounding)
    np.testing.assert_allclose(got.vertices, ref.vertices, rtol=0, atol=1e-12)
    assert got.report.sharp_edges == int(sharp.sum())
    # the same edges as OpenSubdiv crease tags (0-based vertex numbers), faces in one smoothing group
    pairs = mesh.topology.edges[sharp]
    tags = [f"t crease 2/1/0 {a} {b} 3.5" for a, b in pairs[1:]]
    chain = f"t crease 3/2/0 {pairs[0, 0]} {pairs[0, 1]} {pairs[0, 0]} 1.0 0.0"   # the 2nd edge: sharpness 0
    lines = ["v %r %r %r" % tuple(p) for p in mesh.vertices.tolist()] + ["s 1"] + \
        ["f " + " ".join(str(i + 1) for i in f) for f in faces] + tags + [chain]
    q = tmp_path / "creases.obj"
    q.write_text("\n".join(lines) + "\n")
    got = sf.flow(sf.load(q), -10.0, sharp_edges="mesh")
    np.testing.assert_allclose(got.vertices, ref.vertices, rtol=0, atol=1e-12)
    # s off: every edge of such a face is sharp
    r = tmp_path / "off.obj"
    r.write_text("\n".join(["v %r %r %r" % tuple(p) for p in mesh.vertices.tolist()] + ["s off"] +
                           ["f " + " ".join(str(i + 1) for i in f) for f in faces]) + "\n")
    assert sf.flow(sf.load(r), 1.0, sharp_edges="mesh").report.sharp_edges == mesh.topology.n_edges
    assert n == m.n_vertices


def test_bad_crease_tags_are_parameter_errors(tmp_path):
    mesh, _ = fs.box(per_side=1, layers=1)
    base = ["v %r %r %r" % tuple(p) for p in mesh.vertices.tolist()] + \
        ["f " + " ".join(str(i + 1) for i in f) for f in mesh.faces_as_lists()]
    for tag, msg in [("t crease 2/1/0 0 7 2.0", "not an edge"), ("t crease 2/2/0 0 1 2.0 1.0", "chain"),
                     ("t crease 2/1/0 0 1 nan", "not a number")]:
        p = tmp_path / "bad.obj"
        p.write_text("\n".join(base + [tag]) + "\n")
        with pytest.raises(ParameterError, match=msg):
            sf.flow(sf.load(p), 1.0, sharp_edges="mesh")
