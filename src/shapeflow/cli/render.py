"""``shapeflow render MESH [MESH...] OUT.png``: headless pictures (needs ``shapeflow[render]``)."""

from __future__ import annotations

import os

from ..errors import ParameterError
from .common import eprint, load_mesh_arg


def register(sub) -> None:
    p = sub.add_parser(
        "render", help="draw one or more meshes into a PNG (offscreen; needs shapeflow[render])",
        usage="shapeflow render [options] MESH [MESH ...] OUT.png",
        description="Render meshes offscreen into a PNG: smooth or flat shading, a colour field with a "
        "colour bar, optional wireframe (quads drawn as quads). Several meshes are drawn side by side "
        "with one camera and one colour range, so they can be compared.")
    p.add_argument("paths", nargs="+", metavar="PATH",
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
    p.add_argument("--size", "-s", default=None, metavar="WxH",
                   help="picture size for one mesh (default 800x600), size of each panel for several "
                        "(default 400x400)")
    p.add_argument("--grid", nargs="?", const="auto", default=None, metavar="RxC",
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
    p.set_defaults(func=run)


def parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise ParameterError(f"--size must be WIDTHxHEIGHT, e.g. 800x600; got {text!r}") from None
    return w, h


def parse_grid(text: str | None):
    if text is None or text == "auto":
        return text
    try:
        r, c = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise ParameterError(f"--grid must be ROWSxCOLS, e.g. 2x3; got {text!r}") from None
    return r, c


def parse_range(text: str | None):
    if text is None:
        return None
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise ParameterError(f"--range must be LO,HI; got {text!r}") from None
    return lo, hi


def color_arg(text: str):
    """``displacement:REF`` -> ("displacement", reference mesh); anything else is passed on."""
    if text.startswith("displacement:"):
        ref = text.split(":", 1)[1]
        if not ref:
            raise ParameterError("--color displacement:REF needs a reference mesh after the colon")
        return "displacement", load_mesh_arg(ref)
    if text == "displacement":
        raise ParameterError("--color displacement needs a reference: displacement:REF")
    return text, None


def mesh_label(arg: str) -> str:
    if arg.startswith("example:"):
        return arg.split(":", 1)[1]
    return os.path.splitext(os.path.basename(arg))[0]


def check_png(path: str, option: str = "output") -> str:
    """A .png path that can be written (its folder exists...), checked before any work."""
    from ..io import output_target

    if not path.lower().endswith(".png"):
        raise ParameterError(f"{option} {path!r} must be a .png file")
    output_target(path)
    return path


def run(args) -> int:
    import time

    from ..rendering import render, render_meshes

    if len(args.paths) < 2:
        raise ParameterError("give at least one mesh and the PNG to write: shapeflow render MESH OUT.png")
    inputs, out = args.paths[:-1], check_png(args.paths[-1])
    color, reference = color_arg(args.color)
    clim = parse_range(args.clim)
    grid = parse_grid(args.grid)
    t0 = time.perf_counter()
    meshes = [load_mesh_arg(a) for a in inputs]
    if args.labels is not None and len(args.labels) != len(meshes):
        raise ParameterError(f"--labels: {len(args.labels)} titles for {len(meshes)} meshes")
    from .images import up_axis

    up = up_axis(args.up, meshes[0])
    front = None if args.front == "auto" else args.front
    common = dict(color=color, reference=reference, view=args.view, up=up, front=front, edges=args.edges,
                  shading=args.shading, colorbar=not args.no_colorbar, cmap=args.cmap, clim=clim)
    if len(meshes) == 1 and grid is None:
        size = parse_size(args.size) if args.size else (800, 600)
        label = None if args.no_labels or not args.labels else args.labels[0]
        img = render(meshes[0], out, size=size, label=label, **common)
    else:
        size = parse_size(args.size) if args.size else (400, 400)
        labels = None if args.no_labels else (args.labels or [mesh_label(a) for a in inputs])
        img = render_meshes(meshes, out, grid=grid, size=size, labels=labels, framing=args.framing, **common)
    if not args.quiet:
        eprint(f"shapeflow render: {len(meshes)} mesh(es), {img.shape[1]}x{img.shape[0]} pixels "
               f"in {time.perf_counter() - t0:.2f} s -> {out}")
    return 0
