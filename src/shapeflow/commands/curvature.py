"""``curvature IN OUT``: mean curvature per vertex, saved as the attribute ``curvature``."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .common import load_mesh, resolve_output, save_mesh, write_values
from .report import Reporter

__all__ = ["CurvatureOptions", "VALUE_EXTS", "add_parser", "run"]

VALUE_EXTS = (".npy", ".txt")


@dataclass(frozen=True)
class CurvatureOptions:
    """Options of ``curvature``, named as on the command line; ``view``, ``up`` and ``size`` are the
    picture's (``image``), ``size`` held parsed when there is one."""

    area: str = "barycentric"
    image: str | None = None
    view: str = "iso"
    up: str = "auto"
    size: tuple[int, int] | str = "800x600"
    force: bool = False
    quiet: bool = False

    def __post_init__(self):
        if self.image and isinstance(self.size, str):
            from .images import parse_size

            object.__setattr__(self, "size", parse_size(self.size))


def add_parser(sub) -> None:
    """The grammar of ``curvature``."""
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
    p.set_defaults(options=CurvatureOptions)


def run(o: CurvatureOptions, source: str, target: str, report: Reporter) -> None:
    """Write the mean curvature of ``source`` to ``target`` (.ply with the mesh, or .npy/.txt)."""
    from ..operators import mean_curvature

    ext = os.path.splitext(target)[1].lower()
    if ext != ".ply" and ext not in VALUE_EXTS:
        raise ParameterError(f"OUT {target!r}: use .ply (the mesh with a 'curvature' vertex attribute) or "
                             ".npy/.txt (the values alone); OBJ and OFF cannot store vertex attributes")
    if o.image:
        from .images import check_png

        check_png(o.image, "--image")    # rendering works here: checked before anything is written
    out = resolve_output(source, target, o.force, o.image)
    mesh = load_mesh(source, report)
    h = mean_curvature(mesh, area=o.area)
    result = mesh.with_attributes(curvature=h)
    if ext == ".ply":
        save_mesh(out, result, o.force, report)
    else:
        write_values(out, h, o.force)
    if o.image:
        from ..rendering import render
        from .images import up_axis

        render(result, o.image, color="curvature", view=o.view, up=up_axis(o.up, mesh), size=o.size,
               label=f"mean curvature ({o.area} area)")
    if not o.quiet:
        bnd = mesh.topology.boundary_vertex_mask
        inner = h[~bnd] if (~bnd).any() else h
        q = np.percentile(inner, [0, 50, 100]) if inner.size else [0, 0, 0]
        report.message(f"shapeflow curvature: {mesh.n_vertices} vertices, area={o.area}: H min {q[0]:.4g}, "
                       f"median {q[1]:.4g}, max {q[2]:.4g}"
                       + (f" ({int(bnd.sum())} boundary vertices left out)" if bnd.any() else "")
                       + f" -> {out}" + (f", {o.image}" if o.image else ""))
