"""``shapeflow flow | enhance | smooth``: the implicit curvature flow from the command line."""

from __future__ import annotations

import os
import time

from ..errors import ParameterError
from .common import (
    eprint,
    load_mesh_arg,
    note_compiling,
    note_fact,
    option_names,
    option_number,
    progress_callback,
    resolve_output,
    save_mesh,
    warn_degenerate_result,
    welded_for_operator,
)
from .images import add_image_options


def add_flow_options(p) -> None:
    p.add_argument("input", help="mesh file (OBJ, PLY, OFF, STL, glTF/GLB, USD) or example:NAME")
    p.add_argument("output", help="where to write the result (format from the extension)")
    p.add_argument("--lambda-border", type=float, default=0.0, metavar="B",
                   help="λ_b for boundary vertices of open meshes, own sign (default 0: boundary fixed)")
    p.add_argument("--iterations", "-n", type=int, default=1, metavar="N", help="implicit steps (default 1)")
    p.add_argument("--weights", metavar="FILE_OR_ATTRIBUTE",
                   help="per-vertex weights in [0,1]: a .npy/.txt file (one per vertex) or a vertex attribute "
                        "of the input (e.g. 'weight' from a PLY); 0 = untouched")
    p.add_argument("--invert-weights", action="store_true", help="use 1 - weights")
    p.add_argument("--area-normalized", action="store_true",
                   help="area-normalised operator (eq. 9) instead of the scale-invariant normalised one (eq. 10)")
    p.add_argument("--preserve-volume", action="store_true", help="rescale after each step to keep the volume")
    p.add_argument("--axes", default="xyz", help="coordinates that may change, e.g. 'xy' (default xyz)")
    p.add_argument("--compat", choices=["paper", "blender"], default="paper",
                   help="'blender' reproduces Blender's Laplacian Smooth modifier exactly (default: paper)")
    p.add_argument("--scheme", choices=["tqlbo", "blender"], default=None,
                   help="cotangent weights (default: tqlbo, or blender with --compat blender)")
    p.add_argument("--update", choices=["fixed", "recompute"], default="fixed",
                   help="keep the first iteration's operator (Blender) or rebuild it every iteration")
    p.add_argument("--solver", choices=["auto", "cg", "cholesky", "lu", "chebyshev"], default="auto",
                   help="linear solver")
    p.add_argument("--force", action="store_true",
                   help="allow OUTPUT to be the input file, or a read-only file (overwrite it)")
    p.add_argument("--quiet", "-q", action="store_true", help="no progress or summary on stderr")
    add_image_options(p)


def register(sub) -> None:
    p = sub.add_parser("flow", help="smooth (λ > 0) or enhance (λ < 0) with a signed λ",
                       description="Implicit TQLBO curvature flow (eq. 11): λ > 0 smooths, λ < 0 enhances.")
    add_flow_options(p)
    p.add_argument("--lambda", dest="lam", type=float, required=True, metavar="L",
                   help="signed λ: > 0 smooths, < 0 enhances (figures of the paper: +90 .. -400)")
    p.set_defaults(func=run, sign=None)
    for name, sign, text in (("enhance", -1.0, "exaggerate the shape (λ = -strength)"),
                             ("smooth", 1.0, "smooth the shape (λ = +strength)")):
        q = sub.add_parser(name, help=text, description=f"{text[0].upper()}{text[1:]}.")
        add_flow_options(q)
        q.add_argument("--strength", "-s", type=float, required=True, metavar="S", help="strength >= 0")
        q.set_defaults(func=run, sign=sign)


def weights_arg(value: str | None, mesh):
    """A weights file (.npy/.txt) or the name of a vertex attribute of the mesh."""
    if value is None:
        return None
    if value in mesh.attributes:
        return value
    if os.path.exists(value):
        from ..io import load_weights

        return load_weights(value, mesh.n_vertices)
    have = ", ".join(mesh.attributes) or "none"
    raise ParameterError(f"--weights {value!r} is neither a file nor a vertex attribute of the input "
                         f"(attributes: {have})")


def flow_kwargs(args, mesh) -> dict:
    return dict(lam_border=args.lambda_border, iterations=args.iterations,
                normalized=not args.area_normalized, weights=weights_arg(args.weights, mesh),
                invert_weights=args.invert_weights, preserve_volume=args.preserve_volume, axes=args.axes,
                scheme=args.scheme, update=args.update, compat=None if args.compat == "paper" else "blender",
                solver=args.solver)


#: the library's parameters by the options that set them (messages name the option the user wrote)
OPTION_NAMES = {"lam_border": "--lambda-border", "iterations": "--iterations", "axes": "--axes",
                "weights": "--weights", "scheme": "--scheme", "update": "--update", "solver": "--solver",
                "compat": "--compat"}


def lam_from_args(args) -> float:
    """The signed λ from ``--lambda``, or ``--strength`` with the command's sign, checked in the
    option's own name and sign (``--strength inf``: ``--strength must be finite, got inf``)."""
    option_number("--lambda-border", args.lambda_border)
    if args.sign is None:
        return option_number("--lambda", args.lam)
    return args.sign * option_number("--strength", args.strength, lo=0.0)


def run(args) -> int:
    from .. import flow

    lam = lam_from_args(args)
    out_path = resolve_output(args.input, args.output, args.force, args.image)
    t0 = time.perf_counter()
    mesh = load_mesh_arg(args.input, quiet=args.quiet, command=args.command)
    operand, kw, restore = welded_for_operator(mesh, flow_kwargs(args, mesh), args.command, args.quiet)
    note_compiling(("mesh", "operators", "flow", "linalg"), operand.n_vertices, quiet=args.quiet)
    if not args.quiet and operand.n_vertices >= 1_000_000:
        eprint(f"shapeflow {args.command}: solving {args.iterations} implicit step(s) on {operand.n_vertices:,} "
               "vertices")
    with progress_callback(args.iterations, "flow", quiet=args.quiet) as cb, option_names(OPTION_NAMES):
        result = flow(operand, lam, progress=cb, **kw)
    report = result.report
    note_fact("report", report)
    result = restore(result)
    result.report = report
    warn_degenerate_result(args.command, lam, mesh, result)
    save_mesh(out_path, result, args.force, quiet=args.quiet, command=args.command)
    if not args.quiet:
        r = report
        eprint(f"shapeflow {args.command}: λ={lam:g}, {args.iterations} iteration(s), {mesh.n_vertices} vertices: "
               f"{r.summary()}; total {time.perf_counter() - t0:.3f} s -> {out_path}")
    if args.image:
        from .images import flow_image
        flow_image(args, mesh, result, lam)
    return 0
