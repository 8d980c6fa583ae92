"""``shapeflow curvature IN OUT``: mean curvature per vertex, saved as the attribute ``curvature``."""

from __future__ import annotations

import os

import numpy as np

from ..errors import ParameterError
from .common import eprint, load_mesh_arg, resolve_output, save_mesh, write_values

VALUE_EXTS = (".npy", ".txt")


def register(sub) -> None:
    p = sub.add_parser(
        "curvature", help="compute signed mean curvature per vertex (PLY attribute 'curvature')",
        description="Compute the signed mean curvature H of every vertex (1/r on a sphere, positive where "
        "the surface is convex) with the hybrid operator, and write it as the vertex attribute "
        "'curvature' of a PLY file (or the values alone to .npy/.txt). Values at boundary vertices "
        "of open meshes are not curvature (no closed ring); pictures paint them grey.")
    p.add_argument("input", metavar="IN", help="mesh file (OBJ, PLY, OFF, STL, glTF/GLB, USD) or example:NAME")
    p.add_argument("output", metavar="OUT",
                   help="a .ply file (mesh + 'curvature' attribute), or .npy/.txt (one value per vertex)")
    p.add_argument("--area", choices=["barycentric", "ring", "mixed"], default="barycentric",
                   help="vertex area: barycentric (standard, converges to H; default), ring (the paper's "
                        "ring area, about H/3) or mixed (Meyer's mixed Voronoi area)")
    p.add_argument("--image", metavar="PNG",
                   help="also render the mesh coloured by curvature (needs shapeflow[render])")
    p.add_argument("--view", default="iso",
                   help="view for --image (front, back, left, right, top, bottom, iso, or AZ,EL from the "
                        "model's front; default iso)")
    p.add_argument("--up", choices=["auto", "y", "z"], default="auto",
                   help="the model's up axis for --image (default auto: z for STL, y otherwise)")
    p.add_argument("--size", default="800x600", metavar="WxH", help="size of --image (default 800x600)")
    p.add_argument("--force", action="store_true",
                   help="allow OUT to be the input file, or a read-only file (overwrite it)")
    p.add_argument("--quiet", "-q", action="store_true", help="no summary on stderr")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..operators import mean_curvature

    ext = os.path.splitext(args.output)[1].lower()
    if ext != ".ply" and ext not in VALUE_EXTS:
        raise ParameterError(f"OUT {args.output!r}: use .ply (the mesh with a 'curvature' vertex attribute) or "
                             ".npy/.txt (the values alone); OBJ and OFF cannot store vertex attributes")
    if args.image:
        from .render import check_png, parse_size

        check_png(args.image, "--image")
        size = parse_size(args.size)
        from ..rendering import require

        require()  # fail before writing anything
    out = resolve_output(args.input, args.output, args.force, args.image)
    mesh = load_mesh_arg(args.input)
    h = mean_curvature(mesh, area=args.area)
    result = mesh.with_attributes(curvature=h)
    if ext == ".ply":
        save_mesh(out, result, args.force)
    else:
        write_values(out, h, args.force)
    if args.image:
        from ..rendering import render
        from .images import up_axis

        up = up_axis(args.up, mesh)
        render(result, args.image, color="curvature", view=args.view, up=up, size=size,
               label=f"mean curvature ({args.area} area)")
    if not args.quiet:
        bnd = mesh.topology.boundary_vertex_mask
        inner = h[~bnd] if (~bnd).any() else h
        q = np.percentile(inner, [0, 50, 100]) if inner.size else [0, 0, 0]
        eprint(f"shapeflow curvature: {mesh.n_vertices} vertices, area={args.area}: H min {q[0]:.4g}, "
               f"median {q[1]:.4g}, max {q[2]:.4g}"
               + (f" ({int(bnd.sum())} boundary vertices left out)" if bnd.any() else "")
               + f" -> {out}" + (f", {args.image}" if args.image else ""))
    return 0
