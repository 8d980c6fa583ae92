"""``shapeflow info MESH``: counts, boundary, manifoldness, bounding box, warnings."""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import DataLossWarning
from .common import load_mesh_arg


def register(sub) -> None:
    p = sub.add_parser("info", help="describe a mesh: face sizes, boundary loops, manifoldness, warnings",
                       description="Describe a mesh: counts by face size, boundary loops, "
                       "manifoldness, bounding box and anything suspicious.")
    p.add_argument("mesh", help="mesh file (OBJ, PLY, OFF, STL, glTF/GLB, USD) or example:NAME")
    p.set_defaults(func=run)


def run(args) -> int:
    with warnings.catch_warnings():     # what the file loses is reported in the description itself
        warnings.simplefilter("ignore", DataLossWarning)
        mesh = load_mesh_arg(args.mesh, faces=False)
    print(describe(mesh, name=args.mesh))
    return 0


def sharp_lines(mesh, name: str) -> list[str]:
    """The sharp edges at 30° and those the file marks, and the creased edges, with the options that
    keep them (a malformed 't crease' tag is a warning line)."""
    from ..commands.features import file_crease_tags, marked_edges
    from ..errors import ParameterError
    from ..geometry.features import angle_sharp_edges

    at30 = f"{int(angle_sharp_edges(mesh, 30.0).sum())} at 30° (--feature-angle 30 keeps them)"
    try:
        marks = marked_edges(mesh, name)
        _, sharpness = file_crease_tags(mesh, name)
    except ParameterError as exc:
        return [f"  sharp edges     {at30}", f"  warning: {exc}"]
    marked = (f"{marks.count} marked by the file ({marks.sources()}): --keep-marked-edges keeps them"
              if marks.count else "none marked by the file")
    out = [f"  sharp edges     {at30}; {marked}"]
    s = sharpness[sharpness > 0]
    if s.size:
        span = f"{s.min():g}" if s.min() == s.max() else f"{s.min():g} .. {s.max():g}"
        out.append(f"  creased edges   {marks.tags} by 't crease' tags, sharpness {span}: subdivide creases them "
                   "(--no-creases ignores them)")
    else:
        out.append("  creased edges   none")
    return out


def describe(mesh, name: str = "mesh") -> str:
    t = mesh.topology
    lines = [f"{name}"]
    lines.append(f"  vertices        {mesh.n_vertices}")
    by = mesh.face_count_by_size()
    label = {3: "triangles", 4: "quads"}
    parts = [f"{c} {label.get(s, f'{s}-gons')}" for s, c in by.items()]
    lines.append(f"  faces           {mesh.n_faces} ({', '.join(parts) if parts else 'none'})")
    lines.append(f"  edges           {t.n_edges}")
    if mesh.n_faces == 0:
        lines.append("  warning: no faces: a point cloud, not a surface (nothing to smooth or subdivide)")
        return "\n".join(lines)
    ncomp = t.vertex_components[0] - int(np.count_nonzero(t.vertex_corner_count == 0))
    lines.append(f"  components      {ncomp}")
    lines.append(f"  euler char.     {t.euler_characteristic}")
    nb = int(t.boundary_edge_mask.sum())
    if nb:
        lines.append(f"  boundary        {t.boundary_loop_count} loop(s), {nb} edges, "
                     f"{t.boundary_vertices.size} vertices")
    else:
        lines.append("  boundary        none (closed)")
    from ..geometry.weld import WELD_TOL, weld_map

    wmap = weld_map(mesh.vertices, WELD_TOL, mesh.diagonal)
    shared = mesh.n_vertices - (int(wmap.max()) + 1 if wmap.size else 0)
    if shared:
        lines.append(f"  coincident      {shared} vertices share a position with another (seams or a triangle "
                     "soup; the commands weld them for the operator)")
    d = mesh.diagnostics()
    manifold = d.nonmanifold_edges == 0 and d.nonmanifold_vertices == 0
    lines.append(f"  manifold        {'yes' if manifold else 'no'}")
    lines.append(f"  oriented        {'yes' if d.inconsistent_orientation_edges == 0 else 'no'}")
    lines += sharp_lines(mesh, name)
    lo, hi = mesh.bounding_box
    fmt = lambda a: "(" + ", ".join(f"{x:.6g}" for x in a) + ")"  # noqa: E731
    lines.append(f"  bounding box    {fmt(lo)} .. {fmt(hi)}, diagonal {mesh.diagonal:.6g}")
    kinds = []
    if mesh.attributes:
        kinds.append(f"{', '.join(mesh.attributes)} (per vertex)")
    if mesh.corner_attributes:
        kinds.append(f"{', '.join(mesh.corner_attributes)} (per corner)")
    if mesh.face_attributes:
        labels = [f"{k} ({len(v.names)} names)" if hasattr(v, "names") else k for k, v in mesh.face_attributes.items()]
        kinds.append(f"{', '.join(labels)} (per face)")
    for i, k in enumerate(kinds):
        lines.append(f"  {'attributes' if i == 0 else '':16s}{k}")
    for fmt_name, meta in mesh.metadata.items():
        dropped = meta.get("dropped") if isinstance(meta, dict) else None
        if dropped:
            what = ", ".join(f"{n} '{tag}'" for tag, n in dropped.items())
            lines.append(f"  warning: not kept from the {fmt_name.upper()} file: {what} lines")
    for w in d.warnings():
        lines.append(f"  warning: {w}")
    return "\n".join(lines)
