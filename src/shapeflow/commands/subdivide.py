"""``subdivide IN OUT``: Catmull–Clark or simple subdivision, weights and creases carried along.

Creases: an OBJ's ``t crease`` tags by default (``--no-creases`` ignores them), or ``--creases FILE``
(``i j value`` lines, Blender's crease in [0, 1]) instead; the result's creases (the halves of every
creased edge, one level down per level) are written back as ``t crease`` lines of an OBJ output.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from .common import load_mesh, progress, resolve_output, save_mesh, write_values
from .features import EdgeFile, file_crease_tags, read_edge_file, with_crease_tags
from .images import add_image_options, check_picture_path
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
    creases: str | None = None          #: a file of 'i j value' lines (or a .npy (k, 3)) instead of the input's tags
    no_creases: bool = False            #: ignore the input's 't crease' tags
    crease_file: EdgeFile | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.levels < 0:
            raise ParameterError(f"--levels must be >= 0; got {self.levels}")
        if self.creases is not None and self.no_creases:
            raise ParameterError("give --creases FILE or --no-creases, not both")
        if self.creases is not None:
            object.__setattr__(self, "crease_file", read_edge_file(self.creases, "--creases", values=True))


def add_parser(sub) -> None:
    """The grammar of ``subdivide``."""
    p = sub.add_parser(
        "subdivide",
        help="Catmull-Clark or simple subdivision (any mix of triangles, quads, n-gons)",
        description="Subdivide a mesh: Catmull-Clark (as Blender's Subdivision Surface "
        "modifier with limit surface off, creases on) or simple (midpoints). Every face "
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
    p.add_argument("--creases", metavar="FILE",
                   help="crease these edges: a .txt of 'i j value' lines or a .npy (k, 3), 0-based vertex numbers "
                        "and Blender's crease in [0, 1] (1: infinitely sharp); replaces the input's 't crease' tags")
    p.add_argument("--no-creases", action="store_true",
                   help="ignore the input's 't crease' tags (by default an OBJ's tags crease its edges)")
    p.add_argument("--force", action="store_true", help="allow OUT to be the input file, or a read-only file")
    p.add_argument("--quiet", "-q", action="store_true", help="no summary on stderr")
    add_image_options(p)
    p.set_defaults(options=SubdivideOptions)


def _creases(o: SubdivideOptions, mesh, source: str):
    """The library's ``creases`` for ``mesh`` (None, ``"mesh"``: the file's tags, or (pairs, values)),
    how many edges they crease, and where they come from (for the summary)."""
    if o.crease_file is not None:
        values = o.crease_file.values
        return (o.crease_file.pairs_on(mesh), values), int((values > 0).sum()), f"from {o.creases}"
    if o.no_creases:
        return None, 0, ""
    pairs, sharpness = file_crease_tags(mesh, source)
    if not sharpness.size:
        return None, 0, ""
    return "mesh", int((sharpness > 0).sum()), "from the file's 't crease' tags (--no-creases ignores them)"


def _welded_creases(creases, mesh, welded):
    """``creases`` on the numbering of ``welded`` (a pair whose two vertices become one is dropped); the
    file's tags as Blender's values c = sqrt(s/10)."""
    if creases is None or welded is mesh:
        return creases
    from ..subdivision.rules import sharpness_crease

    if isinstance(creases, str):                  # "mesh": the tags, read (and checked) before
        pairs, sharpness = file_crease_tags(mesh, "")
        values = sharpness_crease(sharpness)
    else:
        pairs, values = creases
    p = welded.weld_map[pairs]
    keep = p[:, 0] != p[:, 1]
    return p[keep], np.asarray(values)[keep]


def _say_lost_creases(out, target: str) -> None:
    """A warning when the result has creases and ``target`` is not an OBJ file (the one that keeps them)."""
    import os
    import warnings

    from ..errors import DataLossWarning

    creases = getattr(out, "creases", None)
    ext = os.path.splitext(target)[1].lower()
    if creases is not None and ext != ".obj" and (np.asarray(creases[1]) > 0).any():
        n = int((np.asarray(creases[1]) > 0).sum())
        warnings.warn(DataLossWarning(f"{target}: the result's {n} creased edges are not written ({ext[1:].upper()} "
                                      "cannot store creases; an OBJ output keeps them as 't crease' lines)"),
                      stacklevel=2)


def run(o: SubdivideOptions, source: str, target: str, report: Reporter) -> None:
    """Subdivide ``source`` and write ``target`` (and ``o.weights_out``, ``o.image``)."""
    from ..geometry.weld import weld_if_split
    from ..io.weights import load_weights
    from ..subdivision import subdivide

    resolve_output(source, target, o.force, o.image, o.weights_out)
    if o.image:
        check_picture_path(o.image)    # the picture can be drawn, before any work
    mesh = load_mesh(source, report)
    if o.weights:
        mesh = mesh.with_weights(load_weights(o.weights, mesh.n_vertices))
    creases, n_creased, crease_source = _creases(o, mesh, source)
    welded = weld_if_split(mesh)
    if welded is not mesh:   # a soup or split seams would subdivide as separate patches
        if not o.quiet:
            report.message(f"shapeflow subdivide: {mesh.n_vertices - welded.n_vertices} vertices coincide with "
                           f"others (seams or a triangle soup): welded to {welded.n_vertices} before subdividing "
                           "(corner attributes such as UVs keep their seams)")
        creases = _welded_creases(creases, mesh, welded)
    t0 = time.perf_counter()
    with progress(report, o.levels, "levels") as cb:
        out = subdivide(welded, o.levels, scheme=o.scheme, boundary=o.boundary, weights_rule=o.weights_rule,
                        progress=cb, creases=creases)
    dt = time.perf_counter() - t0
    if o.weights_out and out.weights is None:
        raise ParameterError("--weights-out: the mesh has no weights (give --weights)")
    _say_lost_creases(out, target)
    save_mesh(target, with_crease_tags(out, o.levels > 0 or welded is not mesh), o.force, report)
    if o.weights_out:
        write_values(o.weights_out, out.weights, o.force)
    if not o.quiet:
        creased = f"; {n_creased} creased edges {crease_source}" if n_creased else ""
        report.message(
            f"shapeflow subdivide: {welded.n_vertices} vertices, {welded.n_faces} faces -> "
            f"{out.n_vertices} vertices, {out.n_faces} faces "
            f"({o.scheme}, {o.levels} level{'s' if o.levels != 1 else ''}) in {dt:.3f} s{creased}"
        )
    if o.image:
        from .images import subdivide_image

        subdivide_image(o, welded, out, report)
