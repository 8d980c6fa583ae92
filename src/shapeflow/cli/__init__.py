"""The ``shapeflow`` command line.

Each subcommand lives in its own module of this package with a
``register(subparsers)`` function; errors become one line on stderr and exit
code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import contextvars
import difflib
import importlib
import os
import re
import signal
import sys
import threading
import warnings

from .. import accel
from ..errors import DataLossWarning, OptionalDependencyError, ParameterError, ShapeflowError

#: subcommand modules, in the order ``--help`` lists them
# (flow.py registers flow, enhance and smooth)
COMMANDS = ["info", "flow", "subdivide", "family", "brush", "render", "curvature", "batch", "studio"]


_NUM = r"(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity|nan"
#: numbers written as option values, negative ones included (-5, -1e3, -.5, -inf, -90,10): values, not options
_NUMBER = re.compile(rf"^-({_NUM})(,\s*[-+]?({_NUM}))*$", re.IGNORECASE)
#: the parser that parses now (the subcommand's once it has begun): errors are told in its name
_ACTIVE: contextvars.ContextVar = contextvars.ContextVar("shapeflow_cli_parser", default=None)


class CommandParser(argparse.ArgumentParser):
    """The command line's parser: every usage error is one line in the user's terms with a hint,
    ``shapeflow enhance: error: unrecognized argument --strenght; did you mean --strength? (see
    'shapeflow enhance --help')``, never a usage dump; misspelt commands, options and choices get a
    "did you mean" (difflib); negative numbers such as ``-1e3`` and ``-inf`` are values."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self._negative_number_matcher = _NUMBER
        self._words: list[str] = []

    def parse_known_args(self, args=None, namespace=None):
        self._words = list(sys.argv[1:] if args is None else args)
        _ACTIVE.set(self)
        return super().parse_known_args(args, namespace)

    def error(self, message):
        parser = self.teller(message)
        print(f"{parser.prog}: error: {parser.explain(message)} (see '{parser.prog} --help')", file=sys.stderr)
        sys.exit(2)

    def teller(self, message: str) -> CommandParser:
        """The parser whose terms tell the error: the top level reports a subcommand's stray words
        ("unrecognized arguments"), which the subcommand tells unless they came before it."""
        active = _ACTIVE.get()
        if message.startswith("unrecognized arguments") and isinstance(active, CommandParser) \
                and active is not self and self._unknown_option() is None:
            return active
        return self

    # -- the message ---------------------------------------------------------------------------

    def explain(self, message: str) -> str:
        """argparse's ``message`` in one line of the user's terms."""
        unknown = self._unknown_option()
        if unknown is not None and not message.startswith("argument COMMAND"):
            return unknown
        m = re.match(r"argument (\S+): invalid choice: '(.*)' \(choose from (.*)\)$", message)
        if m:
            name, value = m.group(1), m.group(2)
            choices = re.findall(r"'([^']*)'", m.group(3)) or [c.strip() for c in m.group(3).split(",")]
            if name == "COMMAND":
                return f"unknown command {value!r}{_did_you_mean(value, choices)}"
            return f"{_long(name)} must be one of {', '.join(choices)}, got {value!r}{_did_you_mean(value, choices)}"
        m = re.match(r"argument (\S+): invalid (float|int) value: '(.*)'$", message)
        if m:
            kind = "a number" if m.group(2) == "float" else "an integer"
            return f"{_long(m.group(1))} must be {kind}, got {m.group(3)!r}"
        m = re.match(r"argument (\S+): expected one argument$", message)
        if m:
            return f"{_long(m.group(1))} needs a value"
        m = re.match(r"the following arguments are required: (.*)$", message)
        if m:
            names = [_long(n) for n in m.group(1).split(", ")]
            return f"missing {', '.join(names)} (required)"
        m = re.match(r"unrecognized arguments: (.*)$", message)
        if m:
            return f"unexpected argument(s) {m.group(1)}"
        return message[0].lower() + message[1:] if message else "bad usage"

    def _unknown_option(self) -> str | None:
        """The first word that looks like an option of this parser and is none, with a suggestion."""
        known = sorted(self._option_string_actions)
        for word in self._words:
            if word == "--":
                return None
            if self._subcommand_word(word):
                return None     # the rest is the subcommand's
            if not word.startswith("-") or word == "-" or _NUMBER.match(word):
                continue
            name = word.split("=", 1)[0]
            if name in known or (name.startswith("--") and len([k for k in known if k.startswith(name)]) == 1):
                continue
            if not name.startswith("--") and len(name) > 2 and name[:2] in known:
                continue        # -n3: a short option with its value attached
            return f"unrecognized argument {name}{_did_you_mean(name, [k for k in known if k.startswith('--')])}"
        return None

    def _subcommand_word(self, word: str) -> bool:
        return any(isinstance(a, argparse._SubParsersAction) and word in a.choices for a in self._actions)


def _long(names: str) -> str:
    """'--strength/-s' -> '--strength'."""
    parts = names.split("/")
    return next((p for p in parts if p.startswith("--")), parts[0])


def _did_you_mean(word: str, choices) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f"; did you mean {close[0]}?" if close else ""


class RaisingParser(CommandParser):
    """An argument parser whose errors raise :class:`ParameterError` instead of exiting (the batch
    runner checks each step of an operation with it)."""

    def error(self, message):
        parser = self.teller(message)
        raise ParameterError(f"{parser.prog}: {parser.explain(message)}")


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
        try:
            mod = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:  # a command whose module is not written yet
            if exc.name == f"{__name__}.{name}":
                continue
            raise
        mod.register(sub)
    for cmd in sub.choices.values():   # `shapeflow flow ... --debug` as well as `shapeflow --debug flow ...`
        cmd.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                         help="show the Python traceback of an unexpected error")
    return parser




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
