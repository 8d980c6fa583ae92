"""USD write-back: normals for left-handed and mirrored prims, ``normals`` and ``primvars:normals`` in
each interpolation, time-sampled points, and single layers written as they are.  Stages are built
with pxr here; what is written is read back with pxr and compared with normals derived by hand."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from meshgen import cube_sphere, grid, icosphere

import shapeflow as sf
from shapeflow.errors import DataLossWarning

pytest.importorskip("pxr", reason="usd-core (the 'usd' extra) is not installed")
from pxr import Gf, Sdf, Usd, UsdGeom, Vt  # noqa: E402


def vec3(a):
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, np.float32))


def define(stage, path, mesh, *, left=False):
    """A Mesh prim with the mesh's faces (reversed and marked leftHanded if ``left``)."""
    m = UsdGeom.Mesh.Define(stage, path)
    faces = [f[::-1] if left else f for f in mesh.faces_as_lists()]
    m.GetPointsAttr().Set(vec3(mesh.vertices))
    m.GetFaceVertexCountsAttr().Set(Vt.IntArray([len(f) for f in faces]))
    m.GetFaceVertexIndicesAttr().Set(Vt.IntArray([i for f in faces for i in f]))
    if left:
        m.GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)
    return m


def file_data(prim):
    """What pxr reads: local points, counts, indices, orientation."""
    m = UsdGeom.Mesh(prim)
    P = np.asarray(m.GetPointsAttr().Get(), np.float64)
    c = np.asarray(m.GetFaceVertexCountsAttr().Get())
    i = np.asarray(m.GetFaceVertexIndicesAttr().Get())
    return P, c, i, m.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded


def hand_face_areas(P, c, i, left):
    """Vector area of each polygon, ½ Σ p_k × p_k+1 in the file's winding; USD's leftHanded
    orientation means clockwise around the normal, so its normal is the negated one."""
    out, o = [], 0
    for k in c:
        poly = P[i[o:o + k]]
        out.append(0.5 * np.cross(poly, np.roll(poly, -1, axis=0)).sum(axis=0))
        o += k
    a = np.array(out)
    return -a if left else a


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def hand_vertex_normals(P, c, i, left):
    a = hand_face_areas(P, c, i, left)
    acc = np.zeros_like(P)
    np.add.at(acc, i, np.repeat(a, c, axis=0))
    return unit(acc)


@pytest.fixture
def scene(tmp_path):
    """/L: a left-handed sphere with vertex ``normals``; /Mirror: a right-handed sphere under a mirroring
    scale with indexed face-varying ``primvars:normals``; /Box: a quad box with uniform ``primvars:normals``
    and face-varying ``normals`` split at every edge (hard edges); /Plate: a bumpy rotated sheet with one
    constant normal."""
    path = tmp_path / "scene.usda"
    stage = Usd.Stage.CreateNew(str(path))
    ball = icosphere(2)
    left = define(stage, "/L", ball, left=True)
    left.AddTranslateOp().Set(Gf.Vec3d(3, 0, 0))
    left.GetNormalsAttr().Set(vec3(ball.vertices))
    left.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mirror = define(stage, "/Mirror", ball)
    mirror.AddTranslateOp().Set(Gf.Vec3d(-3, 0, 0))
    mirror.AddScaleOp().Set(Gf.Vec3f(-1.0, 1.5, 1.0))
    pv = UsdGeom.PrimvarsAPI(mirror.GetPrim()).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray,
                                                            UsdGeom.Tokens.faceVarying)
    pv.Set(vec3(ball.vertices))
    pv.SetIndices(Vt.IntArray.FromNumpy(ball.face_indices.astype(np.int32)))
    box = cube_sphere(3, mix=0.0)
    box = box.with_vertices(np.clip(box.vertices * 1.5, -1, 1) + [0, 0, 4])
    b = define(stage, "/Box", box)
    fa = hand_face_areas(box.vertices, box.face_sizes, box.face_indices, False)
    pvb = UsdGeom.PrimvarsAPI(b.GetPrim()).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray,
                                                        UsdGeom.Tokens.uniform)
    pvb.Set(vec3(unit(fa)))
    b.GetNormalsAttr().Set(vec3(np.repeat(unit(fa), box.face_sizes, axis=0)))
    b.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
    sheet = grid(5, z=lambda x, y: 0.3 * np.sin(x) * np.cos(y))
    plate = define(stage, "/Plate", sheet)
    plate.AddTranslateOp().Set(Gf.Vec3d(0, 0, -6))
    plate.AddRotateXOp().Set(70.0)
    plate.GetNormalsAttr().Set(vec3([[0, 0, 1]]))
    plate.SetNormalsInterpolation(UsdGeom.Tokens.constant)
    stage.GetRootLayer().Save()
    return path


def test_read_winds_every_face_around_its_outward_normal(scene):
    m = sf.load(scene)
    stage = Usd.Stage.Open(str(scene))
    centres = {"L": [3, 0, 0], "Mirror": [-3, 0, 0]}
    from shapeflow.geometry.measures import face_vector_areas

    fa = face_vector_areas(m)
    centroids = np.add.reduceat(m.vertices[m.face_indices], m.face_offsets[:-1], axis=0) / m.face_sizes[:, None]
    for k, (name, c) in enumerate(centres.items()):
        rows = m.face_attributes["object"] == k
        out = np.einsum("ij,ij->i", fa[rows], centroids[rows] - c)
        assert (out > 0).all(), name       # counter-clockwise around the outward normal
    # the normals read (primvars:normals wins for /Box: uniform) are the outward ones, placed in the world
    world = np.asarray(UsdGeom.Xformable(stage.GetPrimAtPath("/Mirror")).ComputeLocalToWorldTransform(0)).T
    assert np.linalg.det(world[:3, :3]) < 0
    n = m.corner_attributes["normal"]
    corner_obj = np.repeat(m.face_attributes["object"], m.face_sizes)
    pos = m.vertices[m.face_indices]
    for k, c in enumerate(centres.values()):
        sel = corner_obj == k
        assert (np.einsum("ij,ij->i", n[sel], pos[sel] - c) > 0).all()


def test_smoothed_normals_are_outward_in_every_interpolation(scene, tmp_path):
    m = sf.load(scene)
    result = sf.smooth(m, 3.0)
    out = tmp_path / "out.usda"
    with warnings.catch_warnings():
        warnings.simplefilter("error")         # nothing is lost: no warning
        sf.save(out, result)
    stage = Usd.Stage.Open(str(out))
    # /L: vertex normals of the left-handed sphere, derived by hand from what pxr reads
    P, c, i, left = file_data(stage.GetPrimAtPath("/L"))
    assert left
    got = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/L")).GetNormalsAttr().Get(), np.float64)
    np.testing.assert_allclose(got, hand_vertex_normals(P, c, i, left), atol=2e-6)
    assert (np.einsum("ij,ij->i", got, P - P.mean(axis=0)) > 0).all()
    # /Mirror: face-varying primvar (indexed in the input), one split group per vertex: written flat
    prim = stage.GetPrimAtPath("/Mirror")
    P, c, i, left = file_data(prim)
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals")
    assert not pv.IsIndexed() and pv.GetInterpolation() == UsdGeom.Tokens.faceVarying
    got = np.asarray(pv.ComputeFlattened(), np.float64)
    np.testing.assert_allclose(got, hand_vertex_normals(P, c, i, False)[i], atol=2e-6)
    assert (np.einsum("ij,ij->i", got, P[i] - P.mean(axis=0)) > 0).all()
    # /Box: uniform primvar = face normals; face-varying `normals` keeps its hard edges: the corners of a
    # vertex that had the same normal (the same side of the box) share one, the others do not
    prim = stage.GetPrimAtPath("/Box")
    P, c, i, left = file_data(prim)
    fa = hand_face_areas(P, c, i, False)
    np.testing.assert_allclose(np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals").Get(), np.float64),
                               unit(fa), atol=2e-6)
    src = Usd.Stage.Open(str(scene))
    before = np.asarray(UsdGeom.Mesh(src.GetPrimAtPath("/Box")).GetNormalsAttr().Get())
    groups: dict = {}
    for corner, (v, f) in enumerate(zip(i, np.repeat(np.arange(c.size), c))):
        groups.setdefault((int(v), tuple(before[corner])), []).append(f)
    want = np.array([unit(fa[groups[(int(v), tuple(before[k]))]].sum(axis=0)) for k, v in enumerate(i)])
    assert len(groups) > len(P)          # there are hard edges
    np.testing.assert_allclose(np.asarray(UsdGeom.Mesh(prim).GetNormalsAttr().Get(), np.float64), want, atol=2e-6)
    # /Plate: the one constant normal, the area-weighted mean over its faces
    P, c, i, left = file_data(stage.GetPrimAtPath("/Plate"))
    got = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/Plate")).GetNormalsAttr().Get(), np.float64)
    np.testing.assert_allclose(got, unit(hand_face_areas(P, c, i, False).sum(axis=0, keepdims=True)), atol=2e-6)
    # the positions: each prim in its own coordinates again
    back = sf.load(out)
    np.testing.assert_allclose(back.vertices, result.vertices, atol=1e-5)
    assert back.faces_as_lists() == m.faces_as_lists()


def test_time_sampled_points_are_written_as_the_pose_read(tmp_path):
    path = tmp_path / "anim.usda"
    stage = Usd.Stage.CreateNew(str(path))
    ball = icosphere(1)
    xf = UsdGeom.Xform.Define(stage, "/Rig")
    op = xf.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 1.0)
    op.Set(Gf.Vec3d(5, 0, 0), 2.0)
    anim = define(stage, "/Rig/Anim", ball)
    pts = anim.GetPointsAttr()
    pts.Clear()
    for t, s in ((1.0, 1.0), (2.0, 2.0), (3.0, 3.0)):
        pts.Set(vec3(ball.vertices * s), t)
        anim.GetNormalsAttr().Set(vec3(ball.vertices), t)
    anim.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    define(stage, "/Still", ball).AddTranslateOp().Set(Gf.Vec3d(0, 9, 0))
    stage.GetRootLayer().Save()

    m = sf.load(path)
    np.testing.assert_allclose(m.vertices[:ball.n_vertices], ball.vertices, atol=1e-6)   # time 1: scale 1, at 0
    result = sf.smooth(m, 2.0)
    out = tmp_path / "out.usda"
    with pytest.warns(DataLossWarning) as rec:
        sf.save(out, result)
    msg = str(rec[0].message)
    assert "/Rig/Anim at time 1 (points: 3 time samples, normals: 3 time samples)" in msg, msg
    assert "/Still" not in msg
    stage = Usd.Stage.Open(str(out))
    prim = UsdGeom.Mesh(stage.GetPrimAtPath("/Rig/Anim"))
    assert prim.GetPointsAttr().GetNumTimeSamples() == 0 and prim.GetNormalsAttr().GetNumTimeSamples() == 0
    local = np.asarray(prim.GetPointsAttr().Get(2.0), np.float64)      # the same pose at every time
    np.testing.assert_array_equal(local, np.asarray(prim.GetPointsAttr().Get(1.0), np.float64))
    for t in (1.0, 2.0):        # the rig's animation is kept: the pose follows it
        M = np.asarray(prim.ComputeLocalToWorldTransform(t)).T
        np.testing.assert_allclose(local @ M[:3, :3].T + M[:3, 3],
                                   result.vertices[:ball.n_vertices] + [5.0 * (t - 1), 0, 0], atol=1e-5)
    P, c, i, _ = file_data(prim.GetPrim())
    np.testing.assert_allclose(np.asarray(prim.GetNormalsAttr().Get(3.0), np.float64),
                               hand_vertex_normals(P, c, i, False), atol=2e-6)


def test_a_single_layer_is_written_as_it_is(tmp_path):
    """Asset paths stay as written (never resolved to this machine's paths), variants stay variants."""
    (tmp_path / "tex").mkdir()
    (tmp_path / "tex" / "wood.png").write_bytes(b"png")
    path = tmp_path / "prop.usda"
    stage = Usd.Stage.CreateNew(str(path))
    m = define(stage, "/Prop", icosphere(1))
    m.GetPrim().CreateAttribute("inputs:file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath("./tex/wood.png"))
    vs = m.GetPrim().GetVariantSets().AddVariantSet("look")
    for v in ("red", "blue"):
        vs.AddVariant(v)
        vs.SetVariantSelection(v)
        with vs.GetVariantEditContext():
            m.GetPrim().CreateAttribute("tint", Sdf.ValueTypeNames.Float).Set(1.0 if v == "red" else 2.0)
    stage.GetRootLayer().Save()
    (tmp_path / "out").mkdir()
    out = tmp_path / "out" / "prop.usda"
    sf.save(out, sf.smooth(sf.load(path), 1.0))
    layer = Sdf.Layer.FindOrOpen(str(out))
    attr = layer.GetAttributeAtPath("/Prop.inputs:file")
    assert attr.default.path == "./tex/wood.png"
    assert set(layer.GetPrimAtPath("/Prop").variantSets["look"].variants.keys()) == {"red", "blue"}


def test_time_sampled_normals_on_static_points(tmp_path):
    path = tmp_path / "n.usda"
    stage = Usd.Stage.CreateNew(str(path))
    ball = icosphere(1)
    m = define(stage, "/M", ball)
    for t in (1.0, 2.0):
        m.GetNormalsAttr().Set(vec3(ball.vertices), t)
    m.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    stage.GetRootLayer().Save()
    out = tmp_path / "out.usda"
    with pytest.warns(DataLossWarning, match=r"/M at the default time \(normals: 2 time samples\)"):
        sf.save(out, sf.smooth(sf.load(path), 1.0))
    written = Usd.Stage.Open(str(out))
    prim = UsdGeom.Mesh(written.GetPrimAtPath("/M"))
    P, c, i, _ = file_data(prim.GetPrim())
    assert prim.GetNormalsAttr().GetNumTimeSamples() == 0
    np.testing.assert_allclose(np.asarray(prim.GetNormalsAttr().Get(1.0), np.float64),
                               hand_vertex_normals(P, c, i, False), atol=2e-6)
