"""Reading glTF 2.0 / GLB into one :class:`~shapeflow.mesh.Mesh` (see :mod:`shapeflow.io.gltf`)."""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..geometry.placement import orientation, place, place_normals
from ..mesh import Mesh
from .gltf_access import ZeroBudget, accessor, dequantize, read_raw
from .gltf_scene import mesh_placements
from .gltf_source import (
    check_extensions,
    check_images,
    field_int,
    is_int,
    items,
    load_buffers,
    parse_container,
    room,
    source_folder,
)

__all__ = ["read_gltf", "BYTES_PER_ELEMENT"]

TRIANGLES = 4
#: memory estimate per vertex and per corner read (float64 copies of positions, attributes, faces)
BYTES_PER_ELEMENT = 200


def _triangle_primitives(doc: dict, name: str) -> tuple[list, int]:
    """(mesh, primitive, its attributes, the primitive) of every triangle primitive; how many others."""
    out, skipped = [], 0
    for mi, mesh in enumerate(items(doc, "meshes", name)):
        prims = mesh.get("primitives") if isinstance(mesh, dict) else None
        if not isinstance(prims, list):
            raise MeshError(f"{name}: mesh {mi} has no list of primitives")
        for pi, p in enumerate(prims):
            where = f"mesh {mi} primitive {pi}"
            attrs = p.get("attributes") if isinstance(p, dict) else None
            if not isinstance(attrs, dict):
                raise MeshError(f"{name}: {where} has no attributes object")
            mode = field_int(p, "mode", where, name, hi=6, default=TRIANGLES)
            if mode != TRIANGLES or attrs.get("POSITION") is None:
                skipped += 1
                continue
            out.append((mi, pi, attrs, p))
    return out, skipped


class _Reader:
    """Decodes each accessor once (shared accessors are read once) and collects the mesh."""

    def __init__(self, doc: dict, buffers: list, name: str, nbytes: int):
        self.doc, self.buffers, self.name = doc, buffers, name
        self.cache: dict = {}
        self.checks: dict = {}
        self.zeros = ZeroBudget(name, nbytes)

    def checked(self, i, role: str):
        if not is_int(i) or (i, role) not in self.checks:      # a non-integer is refused by accessor()
            self.checks[i, role] = accessor(self.doc, self.buffers, i, self.name, role, zeros=self.zeros)
        return self.checks[i, role]

    def values(self, i, role: str) -> np.ndarray:
        key = (i, role)
        if key not in self.cache:
            a = self.checked(i, role)
            raw = read_raw(self.buffers, a, self.name)
            self.cache[key] = raw if role == "indices" else dequantize(raw, a.normalized)
        return self.cache[key]


def _plan(r: _Reader, prims: list, placement: dict) -> tuple[list, dict]:
    """Check every accessor the primitives use, group primitives sharing positions and placement
    into vertex blocks, and refuse up front what cannot fit in memory."""
    name = r.name
    blocks: dict = {}
    plan, need = [], 0
    for mi, pi, attrs, p in prims:
        where = f"mesh {mi} primitive {pi}"
        pos = r.checked(attrs["POSITION"], "POSITION")
        ext = p.get("extensions")
        if isinstance(ext, dict) and "KHR_draco_mesh_compression" in ext and pos.span is None and pos.sparse is None:
            raise MeshError(f"{name}: {where} is compressed with KHR_draco_mesh_compression and has no "
                            "uncompressed fallback, which shapeflow cannot read")
        for role in ("NORMAL", "TEXCOORD_0", "COLOR_0"):
            if attrs.get(role) is not None and r.checked(attrs[role], role).count != pos.count:
                raise MeshError(f"{name}: {where}: {role} (accessor {attrs[role]}) has "
                                f"{r.checked(attrs[role], role).count} elements, POSITION has {pos.count}")
        idx = p.get("indices")
        corners = r.checked(idx, "indices").count if idx is not None else pos.count
        if corners % 3:
            raise MeshError(f"{name}: {where}: {corners} indices are not whole triangles")
        M = placement.get(mi, np.eye(4))
        key = (attrs["POSITION"], attrs.get("COLOR_0"), M.tobytes())
        if key not in blocks:
            blocks[key] = {"position": attrs["POSITION"], "color": attrs.get("COLOR_0"), "matrix": M,
                           "vertices": pos.count, "mesh": mi}
            need += pos.count
        need += corners
        plan.append((mi, pi, attrs, idx, key))
    room(name, f"the glTF meshes ({need} vertices and corners)", BYTES_PER_ELEMENT * need)
    return plan, blocks


def _block_positions(r: _Reader, blocks: dict) -> list:
    out, base = [], 0
    for b in blocks.values():
        M = b["matrix"]
        if not orientation(M):
            raise MeshError(f"{r.name}: mesh {b['mesh']} is shown by a node whose transform is singular (scale 0)")
        with np.errstate(over="ignore", invalid="ignore"):
            pos = place(r.values(b["position"], "POSITION"), M)
        if not np.isfinite(pos).all():
            raise MeshError(f"{r.name}: accessor {b['position']} (POSITION of mesh {b['mesh']}) placed by its node "
                            "leaves double precision")
        b["base"] = base
        base += b["vertices"]
        out.append(pos)
    return out


def _collect(r: _Reader, plan: list, blocks: dict) -> dict:
    """Faces, corner and vertex attributes and the write-back layout of every planned primitive."""
    F, uv, nrm, col, prim, layout, corner = [], [], [], [], [], [], 0
    for k, (mi, pi, attrs, idx, key) in enumerate(plan):
        b = blocks[key]
        n = b["vertices"]
        ind = (r.values(idx, "indices").reshape(-1).astype(np.int64) if idx is not None else np.arange(n))
        if ind.size and ind.max() >= n:
            raise MeshError(f"{r.name}: mesh {mi} primitive {pi}: index {int(ind.max())} (accessor {idx}) "
                            f"is not below its vertex count {n}")
        F.append(ind + b["base"])
        prim.append(np.full(ind.size // 3, k))
        uv.append(r.values(attrs["TEXCOORD_0"], "TEXCOORD_0")[ind] if attrs.get("TEXCOORD_0") is not None else None)
        nrm.append(place_normals(r.values(attrs["NORMAL"], "NORMAL")[ind], b["matrix"])
                   if attrs.get("NORMAL") is not None else None)
        layout.append({"mesh": mi, "primitive": pi, "key": key, "normal": attrs.get("NORMAL"),
                       "corners": (corner, corner + ind.size)})
        corner += ind.size
    for b in blocks.values():
        col.append(r.values(b["color"], "COLOR_0") if b["color"] is not None else None)
    return {"F": F, "uv": uv, "nrm": nrm, "col": col, "prim": prim, "layout": layout}


def read_gltf(data: bytes, name: str, *, external_files: bool = True) -> Mesh:
    """A glTF / GLB file's triangle meshes as one mesh; ``external_files=False`` refuses every URI
    that is not ``data:`` (a file read on its own, e.g. uploaded)."""
    try:
        return _read(data, name, external_files)
    except MemoryError:     # past the up-front estimates (another process took the memory meanwhile)
        raise MeshError(f"{name}: the glTF file does not fit in the memory available") from None


def _read(data: bytes, name: str, external_files: bool) -> Mesh:
    doc, binary = parse_container(data, name)
    check_extensions(doc, name)
    folder = source_folder(name) if external_files else None
    buffers = load_buffers(doc, binary, folder, name)
    check_images(doc, folder, name)
    placement, shown = mesh_placements(doc, name)
    prims, skipped = _triangle_primitives(doc, name)
    external = sum(len(blob) for b, blob in zip(doc.get("buffers") or [], buffers)
                   if isinstance(b, dict) and isinstance(b.get("uri"), str) and b["uri"][:5].lower() != "data:")
    r = _Reader(doc, buffers, name, len(data) + external)
    plan, blocks = _plan(r, prims, placement)
    if not plan:
        raise MeshError(f"{name}: no triangle mesh in the glTF file")
    V = _block_positions(r, blocks)
    got = _collect(r, plan, blocks)
    repeated = sorted(m for m, k in shown.items() if k > 1)
    if repeated:
        warnings.warn(DataLossWarning(f"{name}: mesh(es) {repeated} are shown by several nodes; each is read "
                                      "once, placed by its first node (written back, every instance changes alike)"),
                      stacklevel=3)
    if skipped:
        warnings.warn(DataLossWarning(f"{name}: {skipped} primitive(s) that are not triangles are not kept"),
                      stacklevel=3)
    number = {key: k for k, key in enumerate(blocks)}
    for item in got["layout"]:
        item["block"] = number[item.pop("key")]
    F = np.concatenate(got["F"])
    corner, attrs = {}, {}
    if all(u is not None for u in got["uv"]):
        corner["uv"] = np.concatenate(got["uv"])
    if all(x is not None for x in got["nrm"]):
        corner["normal"] = np.concatenate(got["nrm"])
    if all(c is not None for c in got["col"]):
        attrs["color"] = np.concatenate([c[:, :3] for c in got["col"]])
    face = {"primitive": np.concatenate(got["prim"])} if len(plan) > 1 else {}
    for b in doc.get("buffers") or []:     # kept as bytes: written again from them
        if isinstance(b, dict) and isinstance(b.get("uri"), str) and b["uri"][:5].lower() == "data:":
            del b["uri"]
    kept = ("position", "matrix", "base", "vertices", "mesh")
    layout = {"document": doc, "buffers": buffers, "folder": folder, "source": name, "faces": F,
              "blocks": [{k: b[k] for k in kept} for b in blocks.values()], "primitives": got["layout"]}
    try:
        return Mesh.from_csr(np.concatenate(V), np.full(F.size // 3, 3), F, attributes=attrs,
                             corner_attributes=corner, face_attributes=face, metadata={"gltf": layout})
    except MeshError as exc:
        raise MeshError(f"{name}: {exc}") from None
