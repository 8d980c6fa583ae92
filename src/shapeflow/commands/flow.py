"""``flow | enhance | smooth``: the implicit curvature flow on one mesh file."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

from .. import params
from ..errors import ParameterError
from .common import (
    load_mesh,
    note_compiling,
    option_names,
    option_number,
    progress,
    resolve_output,
    save_mesh,
    warn_degenerate_result,
    welded_for_operator,
)
from .features import FeatureSettings, add_feature_options, drawn_edges, feature_kwargs
from .images import add_image_options, check_picture_path
from .report import Reporter

__all__ = ["FlowSettings", "FlowOptions", "OPTION_NAMES", "add_parsers", "add_flow_options", "run"]

#: the library's parameters by the options that set them (messages name the option the user wrote)
OPTION_NAMES = {"lam_border": "--lambda-border", "iterations": "--iterations", "axes": "--axes",
                "weights": "--weights", "scheme": "--scheme", "update": "--update", "solver": "--solver",
                "compat": "--compat"}


@dataclass(frozen=True)
class FlowSettings(FeatureSettings):
    """The flow options that ``flow``, ``enhance``, ``smooth`` and ``family`` share, named as on the
    command line (``lambda_border`` is ``--lambda-border``), the sharp-edge ones
    (:class:`~shapeflow.commands.features.FeatureSettings`) among them.  Values are checked as the
    object is made, and errors name the option: ``--iterations must be >= 0, got -1``."""

    lambda_border: float = 0.0
    iterations: int = 1
    weights: str | None = None           #: a .npy/.txt file, or the name of a vertex attribute of the input
    invert_weights: bool = False
    area_normalized: bool = False
    preserve_volume: bool = False
    axes: str = "xyz"
    compat: str = "paper"
    scheme: str | None = None
    update: str = "fixed"
    solver: str = "auto"
    force: bool = False
    quiet: bool = False
    image: str | None = None
    image_up: str = "auto"

    def check_run_settings(self) -> None:
        """The checks of the per-run flow options (iterations, update, axes) that the library makes,
        made now, in the options' names, and of the sharp-edge options (their file read)."""
        from ..flow.options import check_run_options

        with option_names(OPTION_NAMES):
            check_run_options(self.iterations, self.update, self.axes, self.compat == "blender")
        self.check_features()

    def flow_kwargs(self, mesh, source: str = "", command: str = "flow", report: Reporter | None = None) -> dict:
        """The library's keyword arguments (:func:`shapeflow.flow`) for ``mesh`` (the file ``source``),
        weights and sharp edges read; ``report`` hears what the file marks sharp."""
        return dict(lam_border=self.lambda_border, iterations=self.iterations, normalized=not self.area_normalized,
                    weights=weights_arg(self.weights, mesh), invert_weights=self.invert_weights,
                    preserve_volume=self.preserve_volume, axes=self.axes, scheme=self.scheme, update=self.update,
                    compat=None if self.compat == "paper" else "blender", solver=self.solver,
                    **feature_kwargs(self, mesh, source, command, report or Reporter()))


@dataclass(frozen=True)
class FlowOptions(FlowSettings):
    """Options of ``flow`` (``lam``: the signed λ of ``--lambda``), ``enhance`` and ``smooth``
    (``strength``: ``--strength`` >= 0, λ = -strength or +strength)."""

    command: str = "flow"
    lam: float | None = None
    strength: float | None = None

    def __post_init__(self):
        if self.command not in ("flow", "enhance", "smooth"):
            raise ParameterError(f"command must be flow, enhance or smooth, got {self.command!r}")
        option_number("--lambda-border", self.lambda_border)
        self.signed_lambda                   # checks --lambda or --strength, in that option's name and sign
        self.check_run_settings()

    @property
    def signed_lambda(self) -> float:
        """λ: ``--lambda``, or ``--strength`` with the command's sign, checked in the option's own name
        and sign (``--strength inf``: ``--strength must be finite, got inf``); a negative strength
        names the command and the ``flow`` that do what it asks (``enhance -s -50`` smooths)."""
        if self.command == "flow":
            return option_number("--lambda", self.lam)
        sign = -1.0 if self.command == "enhance" else 1.0
        s = self.strength
        if isinstance(s, (int, float)) and -params.LAMBDA_MAX <= s < 0:
            other = "smooth" if self.command == "enhance" else "enhance"
            raise ParameterError(f"--strength must be >= 0, got {s:g} ({self.command}'s λ is {'-' if sign < 0 else '+'}"
                                 f"strength; to {other}, use 'shapeflow {other} --strength {-s:g}' or "
                                 f"'shapeflow flow --lambda {sign * s:g}')")
        return sign * option_number("--strength", s, lo=0.0)


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
    add_feature_options(p)


def add_parsers(sub) -> None:
    """The grammar of ``flow``, ``enhance`` and ``smooth``."""
    p = sub.add_parser("flow", help="smooth (λ > 0) or enhance (λ < 0) with a signed λ",
                       description="Implicit TQLBO curvature flow (eq. 11): λ > 0 smooths, λ < 0 enhances.")
    add_flow_options(p)
    p.add_argument("--lambda", dest="lam", type=float, required=True, metavar="L",
                   help="signed λ: > 0 smooths, < 0 enhances (figures of the paper: +90 .. -400)")
    p.set_defaults(options=FlowOptions)
    for name, text in (("enhance", "exaggerate the shape (λ = -strength)"),
                       ("smooth", "smooth the shape (λ = +strength)")):
        q = sub.add_parser(name, help=text, description=f"{text[0].upper()}{text[1:]}.")
        add_flow_options(q)
        q.add_argument("--strength", "-s", type=float, required=True, metavar="S", help="strength >= 0")
        q.set_defaults(options=FlowOptions)


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


def run(o: FlowOptions, source: str, target: str, report: Reporter) -> None:
    """Flow ``source`` with the options ``o`` and write ``target`` (and ``o.image``)."""
    from .. import flow

    lam = o.signed_lambda
    out_path = resolve_output(source, target, o.force, o.image)
    if o.image:
        check_picture_path(o.image)    # the picture can be drawn, before any work
    t0 = time.perf_counter()
    mesh = load_mesh(source, report, quiet=o.quiet, command=o.command)
    kw = o.flow_kwargs(mesh, source, o.command, report)
    sharp = drawn_edges(mesh, kw) if o.image else None
    operand, kw, restore = welded_for_operator(mesh, kw, o.command, o.quiet, report)
    note_compiling(report, ("mesh", "operators", "flow", "linalg"), operand.n_vertices, quiet=o.quiet,
                   command=o.command)
    if not o.quiet and operand.n_vertices >= 1_000_000:
        report.message(f"shapeflow {o.command}: solving {o.iterations} implicit step(s) on "
                       f"{operand.n_vertices:,} vertices")
    with progress(report, o.iterations, "flow", o.quiet) as cb, option_names(OPTION_NAMES):
        result = flow(operand, lam, progress=cb, **kw)
    flow_report = result.report
    report.fact("report", flow_report)
    result = restore(result)
    result.report = flow_report
    warn_degenerate_result(report, o.command, lam, mesh, result)
    save_mesh(out_path, result, o.force, report, quiet=o.quiet, command=o.command)
    if not o.quiet:
        report.message(f"shapeflow {o.command}: λ={lam:g}, {o.iterations} iteration(s), {mesh.n_vertices} vertices: "
                       f"{flow_report.summary()}; total {time.perf_counter() - t0:.3f} s -> {out_path}")
    if o.image:
        from .images import flow_image

        flow_image(o, mesh, result, lam, report, sharp)
