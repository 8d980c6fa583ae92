"""OpenUSD: a stage built with Pixar's own library in the test, placed by transforms, with polygons,
UVs, normals, a material and two meshes; read where the stage shows it, smoothed, written back with
only points and normals changed."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import need
from meshgen import grid, icosphere

import shapeflow as sf
from shapeflow.errors import MeshError

pxr = need("pxr", "usd-core (the 'usd' extra)")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt  # noqa: E402


def build_stage(path):
    """/World (translate, rotateZ 30°, scale) holding a hybrid sheet with st and vertex normals, and
    /Ball beside it; a material with a custom attribute.  Returns the expected world positions."""
    stage = Usd.Stage.CreateNew(str(path))
    world = UsdGeom.Xform.Define(stage, "/World")
    world.AddTranslateOp().Set(Gf.Vec3d(1.0, -2.0, 0.5))
    world.AddRotateZOp().Set(30.0)
    world.AddScaleOp().Set(Gf.Vec3f(2.0, 2.0, 3.0))
    sheet = grid(8, jitter=0.15, mix=0.4, seed=3, z=lambda x, y: 0.2 * np.sin(x) * np.cos(y))
    m = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    m.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(sheet.vertices.astype(np.float32)))
    m.GetFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(sheet.face_sizes.astype(np.int32)))
    m.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(sheet.face_indices.astype(np.int32)))
    st = np.random.default_rng(0).random((sheet.n_corners, 2))
    UsdGeom.PrimvarsAPI(m.GetPrim()).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                   UsdGeom.Tokens.faceVarying).Set(
        Vt.Vec2fArray.FromNumpy(st.astype(np.float32)))
    m.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(np.tile(np.float32([0, 0, 1]), (sheet.n_vertices, 1))))
    m.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    ball = icosphere(1)
    b = UsdGeom.Mesh.Define(stage, "/Ball")
    b.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 10.0))
    b.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(ball.vertices.astype(np.float32)))
    b.GetFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(ball.face_sizes.astype(np.int32)))
    b.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(ball.face_indices.astype(np.int32)))
    mat = UsdShade.Material.Define(stage, "/Looks/Wood")
    mat.GetPrim().CreateAttribute("studio:grain", Sdf.ValueTypeNames.Float).Set(0.25)
    stage.GetRootLayer().Save()
    a = np.radians(30.0)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    A = R @ np.diag([2.0, 2.0, 3.0])
    expected = np.concatenate([sheet.vertices.astype(np.float32) @ A.T + [1.0, -2.0, 0.5],
                               ball.vertices.astype(np.float32) + [0.0, 0.0, 10.0]])
    return sheet, ball, st, expected, A


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_stage_read_where_it_shows_the_meshes(tmp_path, ext):
    src = tmp_path / f"scene{ext}"
    sheet, ball, st, expected, A = build_stage(src)
    m = sf.load(src)
    np.testing.assert_allclose(m.vertices, expected, atol=1e-5)
    assert m.face_sizes.tolist() == sheet.face_sizes.tolist() + ball.face_sizes.tolist()   # polygons as written
    assert m.face_attributes["object"].tolist() == [0] * sheet.n_faces + [1] * ball.n_faces
    assert "uv" not in m.corner_attributes          # the ball has no st: a corner attribute must cover every corner
    one = sf.load(src)
    assert one.n_vertices == sheet.n_vertices + ball.n_vertices


def test_smoothed_stage_written_back_with_points_and_normals_only(tmp_path):
    from shapeflow.cli import main

    src, out = tmp_path / "scene.usda", tmp_path / "out.usdc"
    sheet, ball, st, expected, A = build_stage(src)
    assert main(["smooth", str(src), str(out), "--strength", "2", "-q"]) == 0
    result = sf.smooth(sf.load(src), 2.0)
    stage = Usd.Stage.Open(str(out))
    assert stage.GetPrimAtPath("/Looks/Wood").GetAttribute("studio:grain").Get() == pytest.approx(0.25)
    sheet_prim = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Sheet"))
    local = np.asarray(sheet_prim.GetPointsAttr().Get(), np.float64)
    world = result.vertices[:sheet.n_vertices]
    np.testing.assert_allclose(local @ A.T + [1.0, -2.0, 0.5], world, atol=1e-5)      # its own coordinates again
    st_back = np.asarray(UsdGeom.PrimvarsAPI(sheet_prim.GetPrim()).GetPrimvar("st").Get(), np.float64)
    np.testing.assert_allclose(st_back, st.astype(np.float32), atol=0)              # untouched
    n = np.asarray(sheet_prim.GetNormalsAttr().Get(), np.float64)
    assert n.shape == (sheet.n_vertices, 3) and np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    assert not np.allclose(n, [0, 0, 1])                                            # recomputed
    np.testing.assert_allclose(sf.load(out).vertices, result.vertices, atol=1e-5)


def test_changed_faces_make_a_new_stage(tmp_path):
    src, out = tmp_path / "scene.usda", tmp_path / "sub.usda"
    build_stage(src)
    m = sf.load(src)
    sub = sf.subdivide(m, 1)
    with pytest.warns(sf.DataLossWarning, match="not written"):
        sf.save(out, sub)
    back = sf.load(out)
    assert back.n_vertices == sub.n_vertices and back.face_sizes.tolist() == sub.face_sizes.tolist()
    np.testing.assert_allclose(back.vertices, sub.vertices, atol=1e-5)


def test_a_malformed_file_names_itself(tmp_path):
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Mesh \"X\" {\n  point3f[] points = [(0, 0\n")
    with pytest.raises(MeshError, match="bad.usda"):
        sf.load(bad)
    empty = tmp_path / "empty.usda"
    stage = Usd.Stage.CreateNew(str(empty))
    stage.GetRootLayer().Save()
    with pytest.raises(MeshError, match="no Mesh prim"):
        sf.load(empty)
