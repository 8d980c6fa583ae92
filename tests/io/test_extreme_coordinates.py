"""Huge and tiny but finite coordinates: read, described, welded and written (or refused by name).

A tetrahedron scaled by 1e-300 .. 1e300 is the same shape: its diagonal is sqrt(3)·s (measured
without squaring), none of its faces is "zero-area", and `shapeflow info` describes it on stdout with
nothing on stderr.  Formats that store float32 (STL, glTF, USD points) refuse coordinates float32
cannot hold with one MeshError naming the output; PLY, OBJ and OFF keep them bit for bit.  Scene
transforms of 1e300 or 1e-110 per axis place their meshes (the determinant of the latter, 1e-330,
underflows when taken directly).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import need
from test_gltf_files import cube, cube_doc

import shapeflow as sf

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "src")
TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
TET_F = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
SCALES = [1e-300, 1e-200, 1e155, 1e200, 1e300]


def tet(scale: float) -> sf.Mesh:
    return sf.Mesh(TET_V * scale, TET_F)


@pytest.mark.parametrize("scale", SCALES + [1.0])
def test_the_mesh_summaries_hold_at_any_scale(scale):
    m = tet(scale)
    assert m.diagonal == pytest.approx(np.sqrt(3) * scale, rel=1e-15)
    d = m.diagnostics()
    assert d.zero_area_faces == 0 and not d.warnings()


@pytest.mark.parametrize("ext", [".ply", ".obj", ".off"])
@pytest.mark.parametrize("scale", SCALES)
def test_double_formats_keep_extreme_coordinates(tmp_path, ext, scale):
    path = tmp_path / f"t{ext}"
    sf.save(path, tet(scale))
    assert np.array_equal(sf.load(path).vertices, TET_V * scale)


@pytest.mark.parametrize("ext, module", [(".stl", None), (".glb", "pygltflib"), (".gltf", "pygltflib"),
                                         (".usda", "pxr"), (".usdc", "pxr")])
@pytest.mark.parametrize("scale, match", [(1e39, r"up to 1e\+39 are beyond float32"),
                                          (1e300, r"up to 1e\+300 are beyond float32"),
                                          (1e-300, r"all below 1.18e-38 in magnitude \(up to 1e-300\) vanish")])
def test_float32_formats_refuse_what_float32_cannot_hold(tmp_path, ext, module, scale, match):
    if module:
        need(module)
    path = tmp_path / f"t{ext}"
    with pytest.raises(sf.MeshError, match=match) as info:
        sf.save(path, tet(scale))
    assert str(info.value).startswith(str(path)) and "write PLY, OBJ or OFF" in str(info.value)
    assert os.listdir(tmp_path) == []                     # nothing written, no temporary left
    sf.save(path, tet(1e38 if scale > 1 else 1e-37))     # the ends of float32's normal range are written
    assert os.listdir(tmp_path) == [path.name]


def usd_with_scale(path, scale, points):
    need("pxr")
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    x = UsdGeom.Xform.Define(stage, "/x")
    x.AddScaleOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(scale, scale, scale))
    m = UsdGeom.Mesh.Define(stage, "/x/m")
    m.GetPointsAttr().Set([Gf.Vec3f(*p) for p in points])
    m.GetFaceVertexCountsAttr().Set([3] * len(TET_F))
    m.GetFaceVertexIndicesAttr().Set([i for f in TET_F for i in f])
    stage.Save()


@pytest.mark.parametrize("scale", [1e300, -1e300, 1e-110, 2.0 ** -340])
def test_a_usd_transform_of_extreme_scale_places_its_mesh(tmp_path, scale):
    src, out = tmp_path / "s.usda", tmp_path / "o.usda"
    usd_with_scale(src, scale, TET_V)
    m = sf.load(src)
    assert np.array_equal(m.vertices, TET_V * scale)
    # a mirroring scale (-1e300: determinant -1e900) reverses the corners, keeping the faces outward
    expected = [f[::-1] for f in TET_F] if scale < 0 else TET_F
    assert [sorted(f) for f in m.faces_as_lists()] == [sorted(f) for f in TET_F]
    assert [f[f.index(min(f)):] + f[:f.index(min(f))] for f in m.faces_as_lists()] == \
        [f[f.index(min(f)):] + f[:f.index(min(f))] for f in expected]
    sf.save(out, m.with_vertices(m.vertices * 0.5))              # written back in the prim's coordinates
    from pxr import Usd

    stage = Usd.Stage.Open(str(out))
    pts = np.array(stage.GetPrimAtPath("/x/m").GetAttribute("points").Get())
    np.testing.assert_allclose(pts, TET_V * 0.5, rtol=1e-7)


def test_usd_points_placed_beyond_double_precision_are_refused(tmp_path):
    src = tmp_path / "s.usda"
    usd_with_scale(src, 1e300, TET_V * 1e10)
    with pytest.raises(sf.MeshError, match=r"/x/m: its points placed by its transform leave double precision"):
        sf.load(src)


@pytest.mark.parametrize("scale", [1e-110, 1e30])
def test_a_gltf_node_of_extreme_scale_places_its_mesh(tmp_path, scale):
    need("pygltflib")
    d = cube_doc()
    d.j["nodes"][0]["scale"] = [scale, scale, scale]
    path = tmp_path / "c.gltf"
    path.write_bytes(d.gltf())
    np.testing.assert_array_equal(sf.load(path).vertices, cube()[0] * np.float64(scale))
    d.j["nodes"][0]["scale"] = [scale, scale, 0.0]
    path.write_bytes(json.dumps(d.j).encode())
    with pytest.raises(sf.MeshError, match="singular"):
        sf.load(path)


def cli(*args, cwd):
    env = dict(os.environ, PYTHONPATH=SRC)
    return subprocess.run([sys.executable, "-m", "shapeflow", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


def test_the_cli_describes_and_refuses_extreme_coordinates_in_one_line(tmp_path):
    big = np.finfo(float).max / 2
    cases = {f"s{s:g}.obj": tet(s) for s in SCALES}
    cases["whole_range.obj"] = sf.Mesh(np.array([[-1, -1, -1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1.0]]) * big,
                                       TET_F)
    for name, m in cases.items():
        sf.save(tmp_path / name, m)
        r = cli("info", name, cwd=tmp_path)
        assert r.returncode == 0 and r.stderr == "", (name, r.stderr)
        assert f"diagonal {m.diagonal:.6g}" in r.stdout and "zero-area" not in r.stdout, r.stdout
    assert "diagonal inf" in cli("info", "whole_range.obj", cwd=tmp_path).stdout
    sf.save(tmp_path / "e100.obj", tet(1e100))
    for src, out, match in [("e100.obj", "o.stl", "beyond float32"), ("s1e-300.obj", "o.stl", "vanish in float32")]:
        r = cli("enhance", src, out, "-s", "1", cwd=tmp_path)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr.startswith(f"shapeflow enhance: error: {out}: ") and match in r.stderr
        assert not (tmp_path / out).exists()
