"""OpenUSD (``.usd``, ``.usda``, ``.usdc``), through Pixar's ``usd-core`` (the ``usd`` extra).

Reading: every ``Mesh`` prim of the stage's default time becomes part of one
:class:`~shapeflow.mesh.Mesh`, placed by its local-to-world transform; USD meshes are
polygon meshes in CSR already (``faceVertexCounts``, ``faceVertexIndices``), so quads and
n-gons stay as they are.  The face attribute ``"object"`` (several prims) says which prim a
face came from; the ``st`` primitive variable becomes the corner attribute ``"uv"``
(face-varying as written, or spread from vertex interpolation), ``normals`` the corner
attribute ``"normal"``, ``displayColor`` (vertex) the vertex attribute ``"color"``.

Writing a mesh read from USD with its faces unchanged (smoothing, enhancement, the brush)
writes the stage back, flattened into one layer, with new ``points`` (each prim in its own
coordinates again) and new normals where the prim had them: materials, other prims,
attributes and metadata pass through.  Any other mesh is written as a new stage with one
``Mesh`` prim (n-gons kept, ``st`` and ``normals`` face-varying, ``displayColor``).
"""

from __future__ import annotations

import os
import tempfile
import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError, OptionalDependencyError
from ..geometry.placement import place, place_normals, unplace, unplace_normals
from ..mesh import Mesh

__all__ = ["read_usd", "write_usd"]


def _pxr():
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("usd-core", "usd", "reading and writing USD", exc) from exc
    return Usd, UsdGeom, Sdf, Gf, Vt


def _world(UsdGeom, Usd, prim) -> np.ndarray:
    """The prim's local-to-world matrix in the column-vector convention (USD stores row vectors)."""
    m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    return np.array(m, dtype=np.float64).T


def _primvar(UsdGeom, prim, name: str, counts, indices):
    """A primvar as per-corner values (face-varying, or vertex spread to the corners), or None."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not pv or not pv.HasValue():
        return None, None
    vals = pv.ComputeFlattened()
    if vals is None:
        return None, None
    arr = np.asarray(vals, dtype=np.float64)
    arr = arr.reshape(arr.shape[0], -1) if arr.ndim else arr.reshape(1, -1)
    interp = pv.GetInterpolation()
    if interp == UsdGeom.Tokens.faceVarying and arr.shape[0] == indices.size:
        return arr, interp
    if interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying) and arr.shape[0] > indices.max(initial=-1):
        return arr[indices], interp
    if interp == UsdGeom.Tokens.uniform and arr.shape[0] == counts.size:
        return np.repeat(arr, counts, axis=0), interp
    if interp == UsdGeom.Tokens.constant and arr.shape[0] >= 1:
        return np.repeat(arr[:1], indices.size, axis=0), interp
    return None, None


def _open(name: str):
    Usd = _pxr()[0]
    try:
        stage = Usd.Stage.Open(name)
    except Exception as exc:   # pxr raises its own error types on a malformed file
        raise MeshError(f"{name}: not a readable USD file ({type(exc).__name__}: {str(exc).strip()[:200]})") from None
    if stage is None:
        raise MeshError(f"{name}: not a readable USD file")
    return stage


def read_usd(data: bytes, name: str) -> Mesh:
    Usd, UsdGeom, *_ = _pxr()
    stage = _open(name)
    V, S, F, uv, nrm, col, obj, layout = [], [], [], [], [], [], [], []
    base = 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        points = mesh.GetPointsAttr().Get()
        counts = mesh.GetFaceVertexCountsAttr().Get()
        indices = mesh.GetFaceVertexIndicesAttr().Get()
        if points is None or counts is None or indices is None or len(points) == 0:
            continue
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        c = np.asarray(counts, dtype=np.int64)
        i = np.asarray(indices, dtype=np.int64)
        if c.sum() != i.size or (i.size and (i.min() < 0 or i.max() >= P.shape[0])):
            raise MeshError(f"{name}: {prim.GetPath()}: faceVertexCounts and faceVertexIndices do not agree "
                            f"with its {P.shape[0]} points")
        M = _world(UsdGeom, Usd, prim)
        if abs(np.linalg.det(M[:3, :3])) < 1e-300:
            raise MeshError(f"{name}: {prim.GetPath()} has a singular transform (scale 0)")
        V.append(place(P, M))
        S.append(c)
        F.append(i + base)
        obj.append(np.full(c.size, len(layout)))
        st, _ = _primvar(UsdGeom, prim, "st", c, i)
        uv.append(st[:, :2] if st is not None else None)
        n_attr = mesh.GetNormalsAttr()
        nv = n_attr.Get() if n_attr and n_attr.HasAuthoredValue() else None
        n_interp = mesh.GetNormalsInterpolation() if nv is not None else None
        if nv is not None:
            nn = np.asarray(nv, dtype=np.float64).reshape(-1, 3)
            nn = nn[i] if nn.shape[0] == P.shape[0] and n_interp != UsdGeom.Tokens.faceVarying else nn
            nrm.append(place_normals(nn, M) if nn.shape[0] == i.size else None)
        else:
            nrm.append(None)
        dc, dc_interp = _primvar(UsdGeom, prim, "displayColor", c, i)
        col.append(dc if dc is not None and dc_interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying)
                   else None)
        layout.append({"path": str(prim.GetPath()), "vertices": P.shape[0], "matrix": M,
                       "normals": None if nv is None else str(n_interp)})
        base += P.shape[0]
    if not V:
        raise MeshError(f"{name}: no Mesh prim with points and faces in the USD stage")
    return _assemble(name, stage, V, S, F, uv, nrm, col, obj, layout)


def _assemble(name, stage, V, S, F, uv, nrm, col, obj, layout) -> Mesh:
    corner, attrs, face = {}, {}, {}
    if all(u is not None for u in uv):
        corner["uv"] = np.concatenate(uv)
    if all(x is not None for x in nrm):
        corner["normal"] = np.concatenate(nrm)
    if all(c is not None for c in col):
        # displayColor is per vertex here: the corners' values back on the vertices
        fi = np.concatenate(F)
        per_corner = np.concatenate(col)
        color = np.zeros((sum(v.shape[0] for v in V), per_corner.shape[1]))
        color[fi] = per_corner
        attrs["color"] = color
    if len(layout) > 1:
        face["object"] = np.concatenate(obj)
    faces = np.concatenate(F)
    try:
        return Mesh.from_csr(np.concatenate(V), np.concatenate(S), faces, attributes=attrs,
                             corner_attributes=corner, face_attributes=face,
                             metadata={"usd": {"layer": stage.Flatten().ExportToString(), "layout": layout,
                                               "faces": faces}})
    except MeshError as exc:
        raise MeshError(f"{name}: {exc}") from None


def write_usd(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None, ext: str = ".usda") -> None:
    """The stage as USD text (``.usda``) or crate (``.usdc``; ``.usd`` is crate)."""
    Usd, UsdGeom, Sdf, Gf, Vt = _pxr()
    meta = mesh.metadata.get("usd", {})
    same = "layer" in meta and np.array_equal(meta.get("faces", np.zeros(0)), mesh.face_indices)
    if "layer" in meta and not same:
        warnings.warn(DataLossWarning("the faces changed (subdivision?): the USD stage of the input is not written, "
                                      "only this mesh"), stacklevel=4)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    if same:
        layer.ImportFromString(meta["layer"])
        stage = Usd.Stage.Open(layer)
        _update(stage, meta["layout"], mesh, UsdGeom, Vt, Gf)
    else:
        stage = Usd.Stage.Open(layer)
        _new_mesh(stage, mesh, UsdGeom, Sdf, Vt, Gf)
    if ext == ".usda" and not binary:
        f.write(stage.GetRootLayer().ExportToString().encode("utf-8"))
        return
    with tempfile.TemporaryDirectory() as tmp:     # the crate format is written to a path only
        path = os.path.join(tmp, "out.usdc")
        stage.GetRootLayer().Export(path)
        with open(path, "rb") as g:
            f.write(g.read())


def _update(stage, layout: list, mesh: Mesh, UsdGeom, Vt, Gf) -> None:
    from ..geometry.normals import vertex_normals

    nrm = vertex_normals(mesh) if any(item["normals"] for item in layout) else None
    base = 0
    for item in layout:
        n = item["vertices"]
        M = np.asarray(item["matrix"])
        local = unplace(mesh.vertices[base:base + n], M)
        prim = UsdGeom.Mesh(stage.GetPrimAtPath(item["path"]))
        prim.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(local, np.float32)))
        if item["normals"] is not None:
            ln = unplace_normals(nrm[base:base + n], M)
            if item["normals"] == str(UsdGeom.Tokens.faceVarying):
                idx = np.asarray(prim.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
                ln = ln[idx]
            prim.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(ln, np.float32)))
        extent = UsdGeom.Boundable.ComputeExtentFromPlugins(UsdGeom.Boundable(prim.GetPrim()), 0)
        if extent:
            prim.GetExtentAttr().Set(extent)
        base += n


def _new_mesh(stage, mesh: Mesh, UsdGeom, Sdf, Vt, Gf) -> None:
    from ..mesh.attributes import expand

    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    prim = UsdGeom.Mesh.Define(stage, "/Mesh")
    stage.SetDefaultPrim(prim.GetPrim())
    prim.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(mesh.vertices, np.float32)))
    prim.GetFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(np.ascontiguousarray(mesh.face_sizes, np.int32)))
    prim.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(np.ascontiguousarray(mesh.face_indices, np.int32)))
    prim.GetSubdivisionSchemeAttr().Set(UsdGeom.Tokens.none)
    pv = UsdGeom.PrimvarsAPI(prim.GetPrim())
    lost = [f"vertex attribute '{k}'" for k in mesh.attributes if k != "color"]
    lost += [f"face attribute '{k}'" for k in mesh.face_attributes]
    for k, v in mesh.corner_attributes.items():
        vals = np.asarray(expand(v), np.float64)
        if k == "uv" and vals.ndim == 2 and vals.shape[1] >= 2:
            st = pv.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
            st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(vals[:, :2], np.float32)))
        elif k == "normal" and vals.ndim == 2 and vals.shape[1] == 3:
            prim.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(vals, np.float32)))
            prim.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
        else:
            lost.append(f"corner attribute '{k}'")
    color = mesh.attributes.get("color")
    if color is not None and color.ndim == 2 and color.shape[1] >= 3:
        c = np.asarray(color[:, :3], np.float64)
        dc = pv.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
        dc.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(np.clip(c / 255.0 if c.max() > 1 else c, 0, 1),
                                                            np.float32)))
    if lost:
        warnings.warn(DataLossWarning("a new USD stage holds positions, polygons, st, normals and displayColor; "
                                      "not kept: " + ", ".join(lost)), stacklevel=5)
    extent = UsdGeom.Boundable.ComputeExtentFromPlugins(UsdGeom.Boundable(prim.GetPrim()), 0)
    if extent:
        prim.GetExtentAttr().Set(extent)
