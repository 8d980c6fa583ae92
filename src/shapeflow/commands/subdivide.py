"""``subdivide IN OUT``: Catmull–Clark or simple subdivision, weights carried along."""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..errors import ParameterError
from .common import load_mesh, progress, resolve_output, save_mesh, write_values
from .images import add_image_options
from .report import Reporter

__all__ = ["SubdivideOptions", "add_parser", "run"]


@dataclass(frozen=True)
class SubdivideOptions:
    """Options of ``subdivide``, named as on the command line (``weights_rule`` is ``--weights-rule``)."""

    levels: int = 1
    scheme: str = "catmull-clark"
    boundary: str = "smooth"
    weights_rule: str = "linear"
    weights: str | None = None          #: a weights file (.npy or text) for the input
    weights_out: str | None = None      #: where to write the subdivided weights too
    force: bool = False
    quiet: bool = False
    image: str | None = None
    image_up: str = "auto"

    def __post_init__(self):
        if self.levels < 0:
            raise ParameterError(f"--levels must be >= 0; got {self.levels}")


def add_parser(sub) -> None:
    """The grammar of ``subdivide``."""
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
    p.set_defaults(options=SubdivideOptions)


def run(o: SubdivideOptions, source: str, target: str, report: Reporter) -> None:
    """Subdivide ``source`` and write ``target`` (and ``o.weights_out``, ``o.image``)."""
    from ..geometry.weld import weld_if_split
    from ..io.weights import load_weights
    from ..subdivision import subdivide

    resolve_output(source, target, o.force, o.image, o.weights_out)
    mesh = load_mesh(source, report)
    if o.weights:
        mesh = mesh.with_weights(load_weights(o.weights, mesh.n_vertices))
    welded = weld_if_split(mesh)
    if welded is not mesh:   # a soup or split seams would subdivide as separate patches
        if not o.quiet:
            report.message(f"shapeflow subdivide: {mesh.n_vertices - welded.n_vertices} vertices coincide with "
                           f"others (seams or a triangle soup): welded to {welded.n_vertices} before subdividing "
                           "(corner attributes such as UVs keep their seams)")
        mesh = welded
    t0 = time.perf_counter()
    with progress(report, o.levels, "levels") as cb:
        out = subdivide(mesh, o.levels, scheme=o.scheme, boundary=o.boundary, weights_rule=o.weights_rule,
                        progress=cb)
    dt = time.perf_counter() - t0
    if o.weights_out and out.weights is None:
        raise ParameterError("--weights-out: the mesh has no weights (give --weights)")
    save_mesh(target, out, o.force, report)
    if o.weights_out:
        write_values(o.weights_out, out.weights, o.force)
    if not o.quiet:
        report.message(
            f"subdivide: {mesh.n_vertices} vertices, {mesh.n_faces} faces -> "
            f"{out.n_vertices} vertices, {out.n_faces} faces "
            f"({o.scheme}, {o.levels} level{'s' if o.levels != 1 else ''}) in {dt:.3f} s"
        )
    if o.image:
        from .images import subdivide_image

        subdivide_image(o, mesh, out, report)
