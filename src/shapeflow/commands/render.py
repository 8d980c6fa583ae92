"""``render MESH [MESH...] OUT.png``: headless pictures (needs ``shapeflow[render]``)."""

from __future__ import annotations

import argparse
import os
import re
import time
from dataclasses import dataclass
from typing import Sequence

from ..errors import ParameterError
from .argv import OptionalValue
from .common import load_mesh
from .images import check_png, parse_size, up_axis
from .report import Reporter

__all__ = ["RenderOptions", "add_parser", "parse_feature_lines", "run"]

#: the angle ``--feature-lines`` without a value stands for (degrees)
DEFAULT_FEATURE_ANGLE = 30.0


@dataclass(frozen=True)
class RenderOptions:
    """Options of ``render``, named as on the command line (``clim`` is ``--range``).  ``size``,
    ``grid`` and ``clim`` may be given as the command line writes them (``"800x600"``, ``"2x3"``,
    ``"-1,1"``) and are held parsed; ``color`` ``displacement:REF`` names the reference mesh."""

    color: str = "curvature"
    view: str = "front"
    up: str = "auto"
    front: str = "auto"
    edges: bool = False
    size: tuple[int, int] | str | None = None     #: None: 800x600 for one mesh, 400x400 per panel for several
    grid: tuple[int, int] | str | None = None     #: "auto": near-square
    shading: str = "smooth"
    labels: tuple[str, ...] | None = None
    no_labels: bool = False
    cmap: str | None = None
    clim: tuple[float, float] | str | None = None
    no_colorbar: bool = False
    framing: str = "shared"
    quiet: bool = False
    feature_lines: float | str | None = None     #: an angle in degrees, or "marked": the edges the file marks

    def __post_init__(self):
        if self.feature_lines is not None:
            object.__setattr__(self, "feature_lines", parse_feature_lines(self.feature_lines))
        if isinstance(self.clim, str):
            object.__setattr__(self, "clim", parse_range(self.clim))
        if isinstance(self.grid, str) and self.grid != "auto":
            object.__setattr__(self, "grid", parse_grid(self.grid))
        if isinstance(self.size, str):
            object.__setattr__(self, "size", parse_size(self.size) if self.size else None)
        if self.labels is not None:
            object.__setattr__(self, "labels", tuple(self.labels))
        reference_of(self.color)


class _MeshesThenPicture(argparse.Action):
    """``PATH [PATH ...]``: the meshes (``input``), then the picture (``output``)."""

    def __call__(self, parser, namespace, values, option_string=None):
        namespace.input, namespace.output = list(values[:-1]), values[-1]


def _is_feature_value(text: str) -> bool:
    """A value of ``--feature-lines``: a number or ``marked`` (any other word is a path)."""
    try:
        float(text)
    except ValueError:
        return text == "marked"
    return True


def _is_grid(text: str) -> bool:
    """A value of ``--grid``: ``RxC``, or a word of digits around an x (told as a bad grid), not a path."""
    return re.fullmatch(r"[\d\s]*[xX][\d\s]*", text) is not None


def add_parser(sub) -> None:
    """The grammar of ``render``."""
    p = sub.add_parser(
        "render", help="draw one or more meshes into a PNG (offscreen; needs shapeflow[render])",
        usage="shapeflow render [options] MESH [MESH ...] OUT.png",
        description="Render meshes offscreen into a PNG: smooth or flat shading, a colour field with a "
        "colour bar, optional wireframe (quads drawn as quads). Several meshes are drawn side by side "
        "with one camera and one colour range, so they can be compared.", intermixed=True)
    p.add_argument("paths", nargs="+", metavar="PATH", action=_MeshesThenPicture,
                   help="input meshes (OBJ, PLY, OFF, STL, glTF/GLB, USD, or example:NAME), then the PNG to write")
    p.add_argument("--color", "-c", default="curvature", metavar="FIELD",
                   help="curvature (signed mean curvature; a PLY 'curvature' attribute if present), "
                        "displacement:REF (along REF's normals), weights, none, an attribute name, "
                        "or a colour such as '#4477aa' (default curvature)")
    p.add_argument("--view", "-v", default="front", metavar="VIEW",
                   help="front, back, left, right, top, bottom, iso, or AZIMUTH,ELEVATION in degrees from the "
                        "model's front (azimuth towards its right, elevation towards the top; Blender's views: "
                        "front looks at the side the model faces); default front")
    p.add_argument("--up", choices=["auto", "y", "z"], default="auto",
                   help="the model's up axis (default auto: the file's convention, z for STL, y otherwise)")
    p.add_argument("--front", choices=["auto", "+x", "-x", "+y", "-y", "+z", "-z"], default="auto",
                   help="the axis the model faces (default auto: the bundled examples' own, else +z with y up, "
                        "as glTF and Blender's exporters, and -y with z up, as in Blender)")
    p.add_argument("--edges", "-e", action="store_true", help="draw polygon edges (quads as quads)")
    p.add_argument("--feature-lines", action=OptionalValue, accepts=_is_feature_value, const=DEFAULT_FEATURE_ANGLE,
                   default=None, metavar="DEG|marked",
                   help="draw sharp edges as lines: those whose faces bend by more than DEG degrees (default 30), "
                        "or 'marked': those the file marks (OBJ smoothing-group borders, 't crease' tags); the word "
                        "after it is its value only if it is a number or 'marked'")
    p.add_argument("--size", "-s", default=None, metavar="WxH",
                   help="picture size for one mesh (default 800x600), size of each panel for several "
                        "(default 400x400)")
    p.add_argument("--grid", action=OptionalValue, accepts=_is_grid, const="auto", default=None, metavar="RxC",
                   help="arrange several meshes in a grid: RxC, or near-square without a value "
                        "(default: one row)")
    p.add_argument("--shading", choices=["smooth", "flat"], default="smooth", help="default smooth")
    p.add_argument("--labels", nargs="+", metavar="TEXT",
                   help="one title per mesh (default: file names when there are several meshes)")
    p.add_argument("--no-labels", action="store_true", help="no titles")
    p.add_argument("--cmap", default=None, help="matplotlib colour map (default coolwarm for signed fields, "
                                                "viridis otherwise)")
    p.add_argument("--range", dest="clim", default=None, metavar="LO,HI",
                   help="field range for the colours (default: robust, symmetric for signed fields)")
    p.add_argument("--no-colorbar", action="store_true", help="leave the colour bar out")
    p.add_argument("--framing", choices=["shared", "rows", "each"], default="shared",
                   help="one camera for all meshes (default), one per grid row, or one per mesh")
    p.add_argument("--quiet", "-q", action="store_true", help="no summary on stderr")
    p.set_defaults(options=RenderOptions)


def parse_grid(text: str):
    try:
        r, c = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise ParameterError(f"--grid must be ROWSxCOLS, e.g. 2x3; got {text!r}") from None
    return r, c


def parse_range(text: str):
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise ParameterError(f"--range must be LO,HI; got {text!r}") from None
    return lo, hi


def parse_feature_lines(value) -> float | str:
    """``--feature-lines``: an angle in [0, 180] degrees, or ``"marked"``."""
    if value == "marked":
        return value
    try:
        angle = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"--feature-lines must be an angle in degrees or 'marked', got {value!r}") from None
    from .. import params

    return params.number("--feature-lines", angle, lo=0.0, hi=180.0)


def reference_of(color: str) -> str | None:
    """The reference mesh of ``displacement:REF``, None for any other colour."""
    if color.startswith("displacement:"):
        ref = color.split(":", 1)[1]
        if not ref:
            raise ParameterError("--color displacement:REF needs a reference mesh after the colon")
        return ref
    if color == "displacement":
        raise ParameterError("--color displacement needs a reference: displacement:REF")
    return None


def mesh_label(arg: str) -> str:
    if arg.startswith("example:"):
        return arg.split(":", 1)[1]
    return os.path.splitext(os.path.basename(arg))[0]


def run(o: RenderOptions, source: str | Sequence[str], target: str, report: Reporter) -> None:
    """Draw the mesh ``source`` (or the meshes, side by side) into the PNG ``target``."""
    from ..rendering import render, render_meshes

    inputs = [source] if isinstance(source, str) else list(source)
    if not inputs:
        raise ParameterError("give at least one mesh and the PNG to write: shapeflow render MESH OUT.png")
    out = check_png(target)
    ref = reference_of(o.color)
    color, reference = ("displacement", load_mesh(ref, report)) if ref is not None else (o.color, None)
    t0 = time.perf_counter()
    meshes = [load_mesh(a, report) for a in inputs]
    if o.labels is not None and len(o.labels) != len(meshes):
        raise ParameterError(f"--labels: {len(o.labels)} titles for {len(meshes)} meshes")
    up = up_axis(o.up, meshes[0])
    front = None if o.front == "auto" else o.front
    lines = o.feature_lines
    if lines == "marked":          # the edges each file marks, a malformed tag told with its file's name
        from .features import marked_edges

        lines = [m.topology.edges[marked_edges(m, a).sharp] for m, a in zip(meshes, inputs)]
        lines = lines[0] if len(meshes) == 1 and o.grid is None else lines
    common = dict(color=color, reference=reference, view=o.view, up=up, front=front, edges=o.edges,
                  shading=o.shading, colorbar=not o.no_colorbar, cmap=o.cmap, clim=o.clim, feature_lines=lines)
    if len(meshes) == 1 and o.grid is None:
        label = None if o.no_labels or not o.labels else o.labels[0]
        img = render(meshes[0], out, size=o.size or (800, 600), label=label, **common)
    else:
        labels = None if o.no_labels else (list(o.labels) if o.labels else [mesh_label(a) for a in inputs])
        img = render_meshes(meshes, out, grid=o.grid, size=o.size or (400, 400), labels=labels, framing=o.framing,
                            **common)
    if not o.quiet:
        report.message(f"shapeflow render: {len(meshes)} mesh(es), {img.shape[1]}x{img.shape[0]} pixels "
                       f"in {time.perf_counter() - t0:.2f} s -> {out}")
