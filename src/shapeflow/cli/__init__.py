"""The ``shapeflow`` command line.

The operations (flow, enhance, smooth, subdivide, family, brush, render, curvature) are
:mod:`shapeflow.commands`: each subcommand's words become its options object, and its function runs
with a reporter that prints on stderr.  ``info``, ``batch`` and ``studio`` are modules of this package
with a ``register(subparsers)`` function.  Errors become one line on stderr and exit code 2, never a
traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading
import warnings

from .. import accel, commands
from ..commands.argv import CommandParser, RaisingParser
from ..errors import DataLossWarning, OptionalDependencyError, ShapeflowError

#: subcommands, in the order ``--help`` lists them (flow registers flow, enhance and smooth)
COMMANDS = ["info", "flow", "subdivide", "family", "brush", "render", "curvature", "batch", "studio"]


def build_parser(*, raising: bool = False) -> argparse.ArgumentParser:
    """The ``shapeflow`` parser; ``raising=True``: usage errors raise ParameterError (no exit)."""
    from .. import __version__

    parser = (RaisingParser if raising else CommandParser)(
        prog="shapeflow",
        description="Smooth and enhance polygon meshes (triangles, quads, n-gons) "
        "with the hybrid quad/triangle Laplace-Beltrami operator.",
        epilog="Mesh arguments accept OBJ, PLY, OFF and STL files, glTF/GLB (shapeflow[gltf]) and USD "
        "(shapeflow[usd]), or 'example:NAME' for a mesh bundled with shapeflow (example:spot, example:spot_cage).",
    )
    parser.add_argument("--version", action="version", version=f"shapeflow {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of an unexpected error (for a bug report)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        if name in commands.GRAMMAR:
            commands.GRAMMAR[name](sub)
        else:
            importlib.import_module(f".{name}", __name__).register(sub)
    for cmd in sub.choices.values():   # `shapeflow flow ... --debug` as well as `shapeflow --debug flow ...`
        cmd.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                         help="show the Python traceback of an unexpected error")
        if cmd.get_default("options") is not None:
            cmd.set_defaults(func=run_operation)
    return parser


def run_operation(args) -> int:
    """An operation's command line: its options, then its function, telling the terminal."""
    from .common import Terminal

    commands.run(commands.options_from(args), args.input, args.output, Terminal())
    return 0


class Terminated(BaseException):
    """SIGTERM or SIGHUP arrived: unwinds like Ctrl-C, so every pending output is removed."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _termination_unwinds():
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` (the CLI process only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise Terminated(signum)

    old = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            old[sig] = signal.signal(sig, handler)
    try:
        yield
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:      # --help, --version (0) or a usage error, said in one line (2)
        return int(exc.code or 0)
    if not getattr(args, "func", None):
        names = ", ".join(sorted(parser._subparsers._group_actions[0].choices))
        print(f"shapeflow: error: give a command: {names} (see 'shapeflow --help')", file=sys.stderr)
        return 2
    try:
        # the command is its own application: it takes the measured small-page win (accel docs) unless
        # SHAPEFLOW_SMALL_PAGES=0, for this call only (an embedding program's setting is back afterwards)
        pages = os.environ.get("SHAPEFLOW_SMALL_PAGES", "1").strip().lower() in ("1", "true", "yes", "on")
        with _termination_unwinds(), accel.use(small_pages=pages), warnings.catch_warnings():
            def one_line(message, category, *rest, **kw):
                print(f"shapeflow {args.command}: warning: {message}", file=sys.stderr)

            warnings.simplefilter("always", DataLossWarning)
            warnings.showwarning = one_line       # restored when the block ends
            return int(args.func(args) or 0)
    except Terminated as exc:
        print(f"shapeflow {args.command}: terminated by {signal.Signals(exc.signum).name}; "
              "nothing was left half-written", file=sys.stderr)
        return 128 + exc.signum
    except BrokenPipeError:
        # the reader of our output went away (e.g. `shapeflow info x | head`): not an error to report
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except (ShapeflowError, OptionalDependencyError) as exc:
        print(f"shapeflow {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = f" '{exc.filename}'" if getattr(exc, "filename", None) else ""
        print(f"shapeflow {args.command}: error:{where} {exc.strerror or exc}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"shapeflow {args.command}: error: out of memory", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"shapeflow {args.command}: interrupted", file=sys.stderr)
        return 130
    except RecursionError:
        print(f"shapeflow {args.command}: error: input nested too deeply", file=sys.stderr)
        return 2
    except Exception as exc:   # a bug, not bad input: one line, the traceback on request
        if args.debug:
            raise
        msg = str(exc).splitlines()[0][:300] if str(exc) else ""
        print(f"shapeflow {args.command}: internal error: {type(exc).__name__}: {msg} "
              f"(rerun with --debug for the traceback, and please report it)", file=sys.stderr)
        return 70


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
