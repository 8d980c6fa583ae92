"""The pictures of the commands (need ``shapeflow[render]``): the ``--image FILE`` of the
shape-changing ones, and what every picture path and size is checked with.

Each shape-changing command calls one function here at its end:

* ``flow`` / ``enhance`` / ``smooth``: :func:`flow_image` (before | after, coloured by
  mean curvature with one shared range, so stronger features show as stronger colour; the sharp
  edges the flow kept drawn as lines);
* ``subdivide``: :func:`subdivide_image` (cage | subdivided, with polygon edges);
* ``family`` (figure 1 of the paper): :func:`family_image` (blue → red strip);
* ``brush``: :func:`before_after`.
"""

from __future__ import annotations

from ..errors import ParameterError
from .report import Reporter

#: default picture settings for the before/after images
VIEW = "iso"
PANEL = (480, 440)


def check_png(path: str, option: str = "output") -> str:
    """A .png path that can be written (its folder exists...) and rendering that works here (the
    ``render`` extra, an offscreen OpenGL), checked before any work, so a run that cannot draw its
    picture writes nothing."""
    from ..io import output_target
    from ..rendering import require

    if not path.lower().endswith(".png"):
        raise ParameterError(f"{option} {path!r} must be a .png file")
    output_target(path)
    require()
    return path


def check_picture_path(path: str) -> str:
    return check_png(path, "--image")


def parse_size(text: str) -> tuple[int, int]:
    """``800x600`` (or ``800×600``) as (width, height)."""
    try:
        w, h = (int(x) for x in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise ParameterError(f"--size must be WIDTHxHEIGHT, e.g. 800x600; got {text!r}") from None
    return w, h


def up_axis(choice: str, mesh) -> str:
    """The up axis for a picture: ``y`` or ``z`` as given, or for ``auto`` the file's convention
    (STL, the 3D-printing format: z; OBJ, PLY, OFF and glTF: y)."""
    if choice != "auto":
        return choice
    return "z" if "stl" in getattr(mesh, "metadata", {}) else "y"


def add_image_options(parser, help: str = "also draw input and result side by side (needs shapeflow[render])") -> None:
    """``--image PNG`` and ``--image-up y|z`` (the model's up axis in the picture)."""
    parser.add_argument("--image", metavar="PNG", help=help)
    parser.add_argument("--image-up", "--up", dest="image_up", choices=["auto", "y", "z"], default="auto",
                        help="up axis of the model in the picture (default auto: the file's convention, z for "
                             "STL and y otherwise; z for Blender/CAD exports); --up is the same option, as in "
                             "'shapeflow render'")


def before_after(path: str, before, after, *, label_before: str = "input", label_after: str = "result",
                 color="curvature", edges=False, shading="smooth", view=VIEW, up: str = "auto",
                 quiet: bool = False, report: Reporter | None = None, feature_lines=None, command: str) -> None:
    """Write ``before`` and ``after`` side by side with one camera (and one colour range).

    ``edges`` and ``shading`` may be one value or a pair (before, after); ``feature_lines``: vertex
    pairs drawn as lines on both (:func:`shapeflow.rendering.render_meshes`); ``command`` names the
    command in the line that says where the picture went."""
    from ..rendering import render_meshes

    check_picture_path(path)
    up = up_axis(up, before)
    render_meshes([before, after], path, labels=[label_before, label_after], color=color, edges=edges,
                  shading=shading, view=view, up=up, size=PANEL, feature_lines=feature_lines)
    if not quiet and report is not None:
        report.message(f"shapeflow {command}: image -> {path}")


def flow_image(o, before, after, lam: float, report: Reporter, sharp=None) -> None:
    """``--image`` of flow/enhance/smooth: input and result coloured by mean curvature, the ``sharp``
    edges (vertex pairs) as lines."""
    what = "smoothed" if lam > 0 else "enhanced"
    label = f"{what}, λ={lam:g}" + (f", {o.iterations} iterations" if o.iterations != 1 else "")
    before_after(o.image, before, after, label_before="input", label_after=label, up=o.image_up, quiet=o.quiet,
                 report=report, feature_lines=sharp, command=o.command)


def subdivide_image(o, before, after, report: Reporter) -> None:
    """``--image`` of subdivide: cage and subdivided mesh with their polygon edges."""
    levels = o.levels
    before_after(o.image, before, after, label_before=f"input ({before.n_faces} faces)",
                 label_after=f"{o.scheme}, {levels} level{'s' if levels != 1 else ''} ({after.n_faces} faces)",
                 color="none", edges=True, shading=["flat", "smooth"], up=o.image_up, quiet=o.quiet, report=report,
                 command="subdivide")


def family_image(path: str, meshes, lams, *, view=VIEW, up: str = "auto", max_panels: int = 12,
                 quiet: bool = False, report: Reporter | None = None) -> None:
    """Figure 1 of the paper: a family of shapes in one strip, coloured blue (first) → red (last).

    With more than ``max_panels`` shapes an evenly spaced subset is drawn
    (first and last always included).
    """
    import numpy as np

    from ..rendering import family_colors, render_meshes

    check_picture_path(path)
    meshes, lams = list(meshes), list(lams)
    idx = np.unique(np.round(np.linspace(0, len(meshes) - 1, min(len(meshes), max_panels))).astype(int))
    cols = family_colors(len(meshes))
    rows = 1 if len(idx) <= 6 else 2
    render_meshes([meshes[i] for i in idx], path, colors=[cols[i] for i in idx],
                  labels=[f"λ={lams[i] + 0.0:g}" for i in idx], grid=(rows, int(np.ceil(len(idx) / rows))),
                  view=view, up=up_axis(up, meshes[0]), size=(260, 280))
    if not quiet and report is not None:
        report.message(f"shapeflow family: image -> {path}")
