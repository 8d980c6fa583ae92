"""``shapeflow subdivide IN OUT``: Catmull–Clark or simple subdivision, weights carried along."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .common import eprint, load_mesh_arg, may_need_weld, progress_callback, resolve_output, save_mesh, write_values
from .images import add_image_options


def register(sub) -> None:
    p = sub.add_parser(
        "subdivide",
        help="Catmull-Clark or simple subdivision (any mix of triangles, quads, n-gons)",
        description="Subdivide a mesh: Catmull-Clark (as Blender's Subdivision Surface "
        "modifier with limit surface and creases off) or simple (midpoints). Every face "
        "becomes quads; open boundaries follow the cubic B-spline curve rule; vertex "
        "weights are interpolated.",
    )
    p.add_argument("input", metavar="IN", help="input mesh (OBJ, PLY, OFF, STL, glTF/GLB, USD) or example:NAME")
    p.add_argument("output", metavar="OUT", help="output mesh file (format from the extension)")
    p.add_argument("--levels", "-l", type=int, default=1, metavar="N",
                   help="number of subdivision steps, >= 0 (default 1)")
    p.add_argument("--scheme", choices=["catmull-clark", "simple"], default="catmull-clark",
                   help="subdivision scheme (default catmull-clark)")
    p.add_argument("--boundary", choices=["smooth", "keep-corners"], default="smooth",
                   help="boundary rule: smooth B-spline curves (Blender 'All'), or also keep "
                   "corner vertices in place (Blender 'Keep Corners'); default smooth")
    p.add_argument("--weights-rule", choices=["linear", "smooth"], default="linear",
                   help="how vertex weights are interpolated: linear (as Blender) or with the "
                   "Catmull-Clark stencil (smoother); default linear")
    p.add_argument("--weights", metavar="FILE",
                   help="per-vertex weights in [0, 1] for IN (.npy, or text with one value per "
                   "line); replaces weights stored in IN")
    p.add_argument("--weights-out", metavar="FILE",
                   help="also write the subdivided weights to FILE (.npy or text)")
    p.add_argument("--force", action="store_true", help="allow OUT to be the input file, or a read-only file")
    p.add_argument("--quiet", "-q", action="store_true", help="no summary on stderr")
    add_image_options(p)
    p.set_defaults(func=run)


def _load_weights(path: str, n: int) -> np.ndarray:
    from ..errors import ParameterError

    p = Path(path)
    if p.suffix.lower() == ".npy":
        w = np.load(p, allow_pickle=False)
    else:
        try:
            w = np.loadtxt(p, dtype=np.float64, ndmin=1)
        except ValueError as exc:
            raise ParameterError(f"weights file '{path}': {exc}") from None
    w = np.asarray(w, dtype=np.float64).reshape(-1)
    if w.size != n:
        raise ParameterError(f"weights file '{path}' has {w.size} values; the mesh has {n} vertices")
    return w


def run(args) -> int:
    from ..errors import ParameterError
    from ..subdivision import subdivide

    if args.levels < 0:
        raise ParameterError(f"--levels must be >= 0; got {args.levels}")
    resolve_output(args.input, args.output, args.force, args.image, args.weights_out)
    mesh = load_mesh_arg(args.input)
    if args.weights:
        mesh = mesh.with_weights(_load_weights(args.weights, mesh.n_vertices))
    from ..geometry.weld import weld

    welded = weld(mesh) if may_need_weld(mesh) else mesh
    if welded.n_vertices < mesh.n_vertices:   # a soup or split seams would subdivide as separate patches
        if not args.quiet:
            eprint(f"shapeflow subdivide: {mesh.n_vertices - welded.n_vertices} vertices coincide with others "
                   f"(seams or a triangle soup): welded to {welded.n_vertices} before subdividing "
                   "(corner attributes such as UVs keep their seams)")
        mesh = welded
    t0 = time.perf_counter()
    with progress_callback(args.levels, "levels") as cb:
        out = subdivide(mesh, args.levels, scheme=args.scheme, boundary=args.boundary,
                        weights_rule=args.weights_rule, progress=cb)
    dt = time.perf_counter() - t0
    if args.weights_out and out.weights is None:
        raise ParameterError("--weights-out: the mesh has no weights (give --weights)")
    save_mesh(args.output, out, args.force)
    if args.weights_out:
        write_values(args.weights_out, out.weights, args.force)
    if not args.quiet:
        eprint(
            f"subdivide: {mesh.n_vertices} vertices, {mesh.n_faces} faces -> "
            f"{out.n_vertices} vertices, {out.n_faces} faces "
            f"({args.scheme}, {args.levels} level{'s' if args.levels != 1 else ''}) in {dt:.3f} s"
        )
    if args.image:
        from .images import subdivide_image
        subdivide_image(args, mesh, out)
    return 0
