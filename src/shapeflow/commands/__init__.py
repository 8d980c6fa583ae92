"""The operations of shapeflow's commands, each one function over a typed options object.

An operation (``flow``, ``enhance``, ``smooth``, ``subdivide``, ``family``, ``brush``, ``render``,
``curvature``) lives in a module of this package with three things:

* its options: a frozen dataclass whose fields are named as the command line's options
  (``lambda_border`` is ``--lambda-border``) and which checks their values as it is made, in the
  options' names (``--strength must be finite, got inf``);
* its grammar: ``add_parser(sub)`` (``flow.add_parsers`` for flow, enhance and smooth), the
  argparse sub-parser that names the options class;
* its function ``run(options, source, target, report)``: reads ``source``, writes ``target``, tells a
  :class:`~shapeflow.commands.report.Reporter` what it does, and raises
  :class:`~shapeflow.errors.ShapeflowError` for bad input.

``shapeflow COMMAND`` (:mod:`shapeflow.cli`) parses argv into the options and runs the function with
a reporter that prints; ``shapeflow batch`` (:mod:`shapeflow.batch`) parses its OPERATION once per
run and runs the function on every file with a reporter that collects.

>>> from shapeflow.commands import FlowOptions, run                                   # doctest: +SKIP
>>> run(FlowOptions(command="enhance", strength=50), "in.ply", "out.ply")             # doctest: +SKIP
"""

from __future__ import annotations

from ..errors import ParameterError
from . import brush, curvature, family, flow, render, subdivide
from .argv import CommandParser, RaisingParser, options_from
from .brush import BrushOptions
from .curvature import CurvatureOptions
from .family import FamilyOptions
from .flow import FlowOptions
from .render import RenderOptions
from .report import Collector, Reporter
from .subdivide import SubdivideOptions

__all__ = ["run", "GRAMMAR", "operations_parser", "options_from", "CommandParser", "RaisingParser", "Reporter",
           "Collector", "FlowOptions", "FamilyOptions", "SubdivideOptions", "BrushOptions", "RenderOptions",
           "CurvatureOptions"]

#: the grammar of every operation, by the first command it adds, in the order of ``shapeflow --help``
GRAMMAR = {"flow": flow.add_parsers, "subdivide": subdivide.add_parser, "family": family.add_parser,
           "brush": brush.add_parser, "render": render.add_parser, "curvature": curvature.add_parser}

_RUN = {FlowOptions: flow.run, FamilyOptions: family.run, SubdivideOptions: subdivide.run, BrushOptions: brush.run,
        RenderOptions: render.run, CurvatureOptions: curvature.run}


def run(options, source, target: str, report: Reporter | None = None) -> None:
    """Run the operation of ``options`` on ``source`` (a mesh path or ``example:NAME``; render takes
    several), writing ``target``; ``report`` hears what it does (default: nobody)."""
    function = _RUN.get(type(options))
    if function is None:
        raise ParameterError(f"options must be those of an operation ({', '.join(c.__name__ for c in _RUN)}), "
                             f"got {type(options).__name__}")
    function(options, source, target, report if report is not None else Reporter())


def operations_parser(prog: str = "shapeflow") -> RaisingParser:
    """A parser of the operations alone (``enhance --strength 5 IN OUT``) whose usage errors raise
    :class:`~shapeflow.errors.ParameterError`, as the command line tells them."""
    parser = RaisingParser(prog=prog)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in GRAMMAR.values():
        add(sub)
    return parser
