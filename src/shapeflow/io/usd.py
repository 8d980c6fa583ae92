"""OpenUSD (``.usd``, ``.usda``, ``.usdc``), through Pixar's ``usd-core`` (the ``usd`` extra).

Reading: every ``Mesh`` prim of the stage becomes part of one :class:`~shapeflow.mesh.Mesh`,
placed by its local-to-world transform; USD meshes are polygon meshes in CSR already
(``faceVertexCounts``, ``faceVertexIndices``), so quads and n-gons stay as they are.  The face
attribute ``"object"`` (several prims) says which prim a face came from; the ``st`` primitive
variable becomes the corner attribute ``"uv"``, ``primvars:normals`` (or else ``normals``) the
corner attribute ``"normal"`` (both spread to the corners from any interpolation),
``displayColor`` (vertex) the vertex attribute ``"color"``.  A prim whose ``orientation`` is
``leftHanded``, or whose transform mirrors (negative determinant), has its faces' corners
reversed, so that every face of the mesh winds counter-clockwise around its outward normal.

Time: a prim is read at its default time, or, when its points are time-sampled, at their
earliest time sample (points, topology, normals, primvars and transform all at that time).

Files that refer to other files (:mod:`.usd_layers`): the file's own layer is opened first (``Sdf.Layer``, no
composition) and every path it refers to is checked before any stage is composed.  With
``external_files=False`` any such path is refused (sublayers, references, payloads, value clips,
asset-valued attributes and metadata).  With ``True`` the layers it composes (sublayers,
references, payloads, clips' ``assetPaths`` and ``manifestAssetPath``) must be USD files inside
the file's own folder, after following symbolic links: absolute paths, ``..`` leaving the folder,
links out of it, devices, URIs, format arguments, variable expressions and clip templates are
refused, naming the path; those layers are checked the same way, then the stage is composed from
the very layers that were checked.

Writing a mesh read from USD with its faces unchanged (smoothing, enhancement, the brush)
writes the stage back with new ``points`` (each prim in its own coordinates again) and new
normals wherever the prim had them (``normals`` and ``primvars:normals``, each in its own
interpolation: vertex, varying, faceVarying with its splits kept, uniform, constant; indexed
normals are written flat), and a new ``extent``: materials, other prims, attributes and metadata
pass through.  A file of one layer that composes no file is written as that layer (nothing
flattened, asset paths as written); a stage that composes files (a layer referring to itself
included) is flattened into one layer.  Time-sampled points cannot be kept: the
prim is written as the one pose that was read, and its time-sampled points, normals, extent and
topology lose their samples (the default value is the new pose); a
:class:`~shapeflow.errors.DataLossWarning` names each such prim, attribute, sample count and time.
Any other mesh is written as a new stage with one ``Mesh`` prim (n-gons kept, ``st`` and
``normals`` face-varying, ``displayColor``).
"""

from __future__ import annotations

import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError, OutputError
from ..geometry.placement import orientation, place, place_normals, unplace, unplace_normals
from ..mesh import Mesh
from .atomic import side_file
from .float32 import as_float32
from .usd_layers import open_stage, pxr_diagnostics, pxr_error, pxr_modules

__all__ = ["read_usd", "write_usd"]

# --------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------

def _world(UsdGeom, prim, t) -> np.ndarray:
    """The prim's local-to-world matrix in the column-vector convention (USD stores row vectors)."""
    m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t)
    return np.array(m, dtype=np.float64).T


def _per_corner(vals, interp: str, counts: np.ndarray, indices: np.ndarray):
    """Values of any interpolation spread to the corners (file order), or None if they do not fit."""
    if vals is None:
        return None
    try:
        arr = np.asarray(vals, dtype=np.float64)
    except (TypeError, ValueError):   # a primvar of another type (strings...)
        return None
    if arr.ndim == 0 or arr.size == 0 or not np.isfinite(arr).all():
        return None
    arr = arr.reshape(arr.shape[0], -1)
    if interp == "faceVarying" and arr.shape[0] == indices.size:
        return arr
    if interp in ("vertex", "varying") and arr.shape[0] > indices.max(initial=-1):
        return arr[indices]
    if interp == "uniform" and arr.shape[0] == counts.size:
        return np.repeat(arr, counts, axis=0)
    if interp == "constant":
        return np.repeat(arr[:1], indices.size, axis=0)
    return None


def _primvar(UsdGeom, prim, name: str, t):
    """(values, interpolation) of an authored primvar at time t (an indexed one flattened), or (None, None)."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not pv or not pv.HasAuthoredValue():
        return None, None
    return pv.ComputeFlattened(t), str(pv.GetInterpolation())


def _normals(UsdGeom, mesh, t):
    """The normals the prim shows at time t (``primvars:normals`` wins over ``normals``), their
    interpolation, and every authored normals attribute, to update on writing: [(name, interpolation)]."""
    authored, shown = [], (None, None)
    pv = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar("normals")
    if pv and pv.HasAuthoredValue():
        interp = str(pv.GetInterpolation())
        authored.append(("primvars:normals", interp))
        shown = (pv.ComputeFlattened(t), interp)
    attr = mesh.GetNormalsAttr()
    if attr and attr.HasAuthoredValue():
        interp = str(mesh.GetNormalsInterpolation())
        authored.append(("normals", interp))
        if len(authored) == 1:     # no primvars:normals: the attribute is what shows
            shown = (attr.Get(t), interp)
    return shown[0], shown[1], authored


def reversal(counts: np.ndarray) -> np.ndarray:
    """The corner permutation that reverses every face's corners (its own inverse)."""
    ends = np.cumsum(counts)
    return np.repeat(ends + ends - counts - 1, counts) - np.arange(int(ends[-1]) if counts.size else 0)


def _array(value, name: str, prim, what: str, dtype, width: int | None):
    try:
        a = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise MeshError(f"{name}: {prim.GetPath()}: {what} is not an array of numbers") from exc
    if width is not None and a.ndim == 1 and a.size == 0:
        a = a.reshape(0, width)
    if (width is None and a.ndim != 1) or (width is not None and (a.ndim != 2 or a.shape[1] != width)):
        raise MeshError(f"{name}: {prim.GetPath()}: {what} has the shape {a.shape}")
    return a


def _time(mesh, Usd):
    """The time a prim is read at: the earliest time sample of its points, else the default time."""
    samples = mesh.GetPointsAttr().GetTimeSamples()
    return (Usd.TimeCode(samples[0]), float(samples[0])) if samples else (Usd.TimeCode.Default(), None)


def read_usd(data: bytes, name: str, *, external_files: bool = True) -> Mesh:
    Usd, UsdGeom, *_ = pxr_modules()
    if data.startswith(b"#usda"):      # a text layer: UTF-8, as USD requires
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as exc:
            line = data.count(b"\n", 0, exc.start) + 1
            raise MeshError(f"{name}: line {line}: not UTF-8 text") from None
    with pxr_diagnostics(name, "reading"):     # pxr's warnings: one DataLossWarning, or a MeshError for cycles
        stage, root, composes, parts = _compose(name, external_files, Usd, UsdGeom)
        try:      # the text written back (a damaged crate file may hold strings that are not UTF-8)
            text = stage.Flatten().ExportToString() if composes else root.ExportToString()
        except (RuntimeError, UnicodeError) as exc:
            raise MeshError(f"{name}: the stage cannot be written as text ({pxr_error(exc)})") from exc
    return _assemble(name, text, *parts.values())


def _compose(name: str, external_files: bool, Usd, UsdGeom):
    """The stage, its root layer, whether it composes files, and its Mesh prims read into parts."""
    stage, root, _, composes = open_stage(name, external_files)
    parts = {k: [] for k in ("V", "S", "F", "uv", "nrm", "col", "obj", "layout")}
    base = 0
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        try:
            base += _read_prim(name, prim, base, parts, Usd, UsdGeom)
        except (RuntimeError, UnicodeError) as exc:     # pxr's errors reading a value (Tf.ErrorException)
            raise MeshError(f"{name}: {prim.GetPath()} cannot be read ({pxr_error(exc)})") from exc
    if not parts["V"]:
        raise MeshError(f"{name}: no Mesh prim with points and faces in the USD stage")
    return stage, root, composes, parts


def _read_prim(name, prim, base: int, parts: dict, Usd, UsdGeom) -> int:
    """Append one Mesh prim to ``parts`` (placed in the world, faces counter-clockwise); returns its
    number of points (0: a prim without points or faces, skipped)."""
    mesh = UsdGeom.Mesh(prim)
    t, when = _time(mesh, Usd)
    points = mesh.GetPointsAttr().Get(t)
    counts = mesh.GetFaceVertexCountsAttr().Get(t)
    indices = mesh.GetFaceVertexIndicesAttr().Get(t)
    if points is None or counts is None or indices is None:
        return 0
    P = _array(points, name, prim, "points", np.float64, 3)
    c = _array(counts, name, prim, "faceVertexCounts", np.int64, None)
    i = _array(indices, name, prim, "faceVertexIndices", np.int64, None)
    if P.shape[0] == 0:
        return 0
    if (c < 0).any() or c.sum() != i.size or (i.size and (i.min() < 0 or i.max() >= P.shape[0])):
        raise MeshError(f"{name}: {prim.GetPath()}: faceVertexCounts and faceVertexIndices do not agree "
                        f"with its {P.shape[0]} points")
    M = _world(UsdGeom, prim, t)
    sign = orientation(M)
    if not sign:
        raise MeshError(f"{name}: {prim.GetPath()} has a singular or non-finite transform")
    with np.errstate(over="ignore", invalid="ignore"):
        placed = place(P, M)
    if not np.isfinite(P).all():
        bad = int(np.flatnonzero(~np.isfinite(P).all(axis=1))[0])
        raise MeshError(f"{name}: {prim.GetPath()}: point {bad} is not finite ({P[bad].tolist()})")
    if not np.isfinite(placed).all():
        raise MeshError(f"{name}: {prim.GetPath()}: its points placed by its transform leave double precision "
                        f"(the largest placed coordinate would exceed {np.finfo(float).max:.3g})")
    left = mesh.GetOrientationAttr().Get(t) == UsdGeom.Tokens.leftHanded
    flip = bool(left) != (sign < 0)
    perm = reversal(c) if flip else np.arange(i.size)
    parts["V"].append(placed)
    parts["S"].append(c)
    parts["F"].append(i[perm] + base)
    parts["obj"].append(np.full(c.size, len(parts["layout"])))
    st = _per_corner(*_primvar(UsdGeom, prim, "st", t), c, i)
    parts["uv"].append(st[perm, :2] if st is not None and st.shape[1] >= 2 else None)
    n_vals, n_interp, authored = _normals(UsdGeom, mesh, t)
    nn = _per_corner(n_vals, n_interp, c, i)
    parts["nrm"].append(place_normals(nn[perm], M) if nn is not None and nn.shape[1] == 3 else None)
    dc, dc_interp = _primvar(UsdGeom, prim, "displayColor", t)
    dc = _per_corner(dc, dc_interp, c, i) if dc_interp in ("vertex", "varying") else None
    parts["col"].append(dc[perm] if dc is not None else None)
    parts["layout"].append({"path": str(prim.GetPath()), "vertices": P.shape[0], "faces": c.size, "matrix": M,
                            "flip": flip, "normals": authored, "time": when})
    return P.shape[0]


def _assemble(name, text, V, S, F, uv, nrm, col, obj, layout) -> Mesh:
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
                             metadata={"usd": {"layer": text, "layout": layout, "faces": faces}})
    except MeshError as exc:
        raise MeshError(f"{name}: {exc}") from None


# --------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------

def write_usd(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None, ext: str = ".usda") -> None:
    """The stage as USD text (``.usda``) or crate (``.usdc``; ``.usd`` is crate).  pxr writes a crate
    only to a path: a hidden file beside the output (:func:`~shapeflow.io.atomic.side_file`), read
    back and removed.  Whatever pxr raises is a MeshError (the caller names the output)."""
    Usd, UsdGeom, Sdf, _, Vt = pxr_modules()
    try:
        with pxr_diagnostics("", "writing"):
            _write_usd(f, mesh, binary, ext, Usd, UsdGeom, Sdf, Vt)
    except (RuntimeError, UnicodeError) as exc:     # Tf.ErrorException is a RuntimeError
        raise MeshError(f"the USD library (pxr) cannot write the stage ({pxr_error(exc)})") from exc


def _write_usd(f: BinaryIO, mesh: Mesh, binary, ext: str, Usd, UsdGeom, Sdf, Vt) -> None:
    meta = mesh.metadata.get("usd", {})
    same = "layer" in meta and np.array_equal(meta.get("faces", np.zeros(0)), mesh.face_indices)
    if "layer" in meta and not same:
        warnings.warn(DataLossWarning("the faces changed (subdivision?): the USD stage of the input is not written, "
                                      "only this mesh"), stacklevel=4)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    if same:
        layer.ImportFromString(meta["layer"])
        stage = Usd.Stage.Open(layer)
        _update(stage, meta["layout"], mesh, Usd, UsdGeom, Vt)
    else:
        stage = Usd.Stage.Open(layer)
        _new_mesh(stage, mesh, UsdGeom, Sdf, Vt)
    if ext == ".usda" and not binary:
        f.write(stage.GetRootLayer().ExportToString().encode("utf-8"))
        return
    with side_file(".usdc") as path:               # the crate format is written to a path only
        if not stage.GetRootLayer().Export(path):
            raise OutputError("the USD library (pxr) could not write the crate file beside it")
        with open(path, "rb") as g:
            f.write(g.read())


def prim_normals(interp: str, fa: np.ndarray, counts: np.ndarray, corner_vertex: np.ndarray, n_points: int,
                 authored: np.ndarray | None) -> np.ndarray:
    """Area-weighted normals of one prim for an interpolation (not unit length), from its faces' vector
    areas ``fa`` (faces wound counter-clockwise around the outward normal) and its corners' vertices
    (mesh order): per point (vertex, varying), per face (uniform), one (constant) or per corner
    (faceVarying), which keeps the splits of the ``authored`` per-corner normals: the corners of a
    point that had the same value share the sum over their faces."""
    if interp == "uniform":
        return fa
    if interp == "constant":
        return fa.sum(axis=0, keepdims=True)
    per_corner = np.repeat(fa, counts, axis=0)
    group, k = corner_vertex, n_points                  # vertex, varying: one normal per point
    if interp == "faceVarying":
        key = corner_vertex[:, None].astype(np.float64)
        if authored is not None and authored.shape == (corner_vertex.size, 3):
            key = np.column_stack([key, authored])
        _, group = np.unique(key, axis=0, return_inverse=True)
        group = group.reshape(-1)
        k = int(group.max(initial=-1)) + 1
    acc = np.stack([np.bincount(group, per_corner[:, q], minlength=k) for q in range(3)], axis=1)
    return acc[group] if interp == "faceVarying" else acc


def _set(attr, value, what: str) -> list:
    """Set ``value`` for every time (the attribute's time samples in this layer cleared); returns
    ["what: N time samples"] when there were samples."""
    samples = attr.GetTimeSamples()
    if samples:
        attr.Clear()
    attr.Set(value)
    return [f"{what}: {len(samples)} time samples"] if samples else []


def _update(stage, layout: list, mesh: Mesh, Usd, UsdGeom, Vt) -> None:
    from ..geometry.measures import face_vector_areas, pow2_exponent

    k = pow2_exponent(mesh.vertices)     # only the normals' directions are used: an exact copy in range
    fa_all = face_vector_areas(mesh, np.ldexp(mesh.vertices, -k) if k else None)
    base = fbase = cbase = 0
    frozen = []
    for item in layout:
        n, nf = item["vertices"], item["faces"]
        M = np.asarray(item["matrix"])
        prim = UsdGeom.Mesh(stage.GetPrimAtPath(item["path"]))
        tc = Usd.TimeCode.Default() if item["time"] is None else Usd.TimeCode(item["time"])
        counts = mesh.face_sizes[fbase:fbase + nf]
        nc = int(counts.sum())
        corner_vertex = mesh.face_indices[cbase:cbase + nc] - base
        perm = reversal(counts) if item["flip"] else np.arange(nc)
        changed = []
        if item["time"] is not None:   # the pose read: its topology too, so that every time agrees
            for attr, what in ((prim.GetFaceVertexCountsAttr(), "faceVertexCounts"),
                               (prim.GetFaceVertexIndicesAttr(), "faceVertexIndices")):
                if attr.GetNumTimeSamples():
                    changed += _set(attr, attr.Get(tc), what)
        for attr_name, interp in item["normals"]:
            changed += _write_normals(prim, attr_name, interp, tc, fa_all[fbase:fbase + nf], counts,
                                      corner_vertex, n, perm, M, UsdGeom, Vt)
        with np.errstate(over="ignore", invalid="ignore"):
            local = unplace(mesh.vertices[base:base + n], M)
        local = as_float32(local, "USD points", f"{item['path']}'s points")
        changed = _set(prim.GetPointsAttr(), Vt.Vec3fArray.FromNumpy(local), "points") + changed
        extent = UsdGeom.Boundable.ComputeExtentFromPlugins(UsdGeom.Boundable(prim.GetPrim()),
                                                            Usd.TimeCode.Default())
        if extent:
            changed += _set(prim.GetExtentAttr(), extent, "extent")
        if changed:
            when = "the default time" if item["time"] is None else f"time {item['time']:g}"
            frozen.append(f"{item['path']} at {when} ({', '.join(changed)})")
        base, fbase, cbase = base + n, fbase + nf, cbase + nc
    if frozen:
        warnings.warn(DataLossWarning(
            "USD animation not kept: time-sampled attributes written as the one pose that was read "
            "(at the earliest time sample of the points, if they have samples), the same at every time: "
            + "; ".join(frozen)),
            stacklevel=5)


def _write_normals(prim, attr_name, interp, tc, fa, counts, corner_vertex, n_points, perm, M, UsdGeom, Vt) -> list:
    """New normals for one authored normals attribute, in its interpolation and the prim's coordinates."""
    pv = UsdGeom.PrimvarsAPI(prim.GetPrim()).GetPrimvar("normals") if attr_name == "primvars:normals" else None
    attr = pv.GetAttr() if pv is not None else prim.GetNormalsAttr()
    authored = None
    if interp == "faceVarying":      # its splits: the authored per-corner values, in mesh order
        vals = pv.ComputeFlattened(tc) if pv is not None else attr.Get(tc)
        arr = np.asarray(vals, np.float64).reshape(-1, 3) if vals is not None and len(vals) else None
        authored = arr[perm] if arr is not None and arr.shape[0] == perm.size else None
    world = prim_normals(interp, fa, counts, corner_vertex, n_points, authored)
    if interp == "faceVarying":
        world = world[perm]          # back to the file's corner order
    local = unplace_normals(world, M)
    changed = _set(attr, Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(local, np.float32)), attr_name)
    if pv is not None and pv.IsIndexed():
        pv.BlockIndices()            # written flat: one value per element
    return changed


def _new_mesh(stage, mesh: Mesh, UsdGeom, Sdf, Vt) -> None:
    from ..mesh.attributes import expand

    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    prim = UsdGeom.Mesh.Define(stage, "/Mesh")
    stage.SetDefaultPrim(prim.GetPrim())
    prim.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(as_float32(mesh.vertices, "USD points")))
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
