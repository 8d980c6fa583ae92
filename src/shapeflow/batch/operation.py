"""The OPERATION of a batch: one or more single-file commands, checked once, run per file.

An operation is what follows ``shapeflow batch INPUTS OUTDIR``: a command of the
single-file CLI with its options, without its input and output (``enhance
--strength 50``), or a pipeline of them joined by ``--then`` (``smooth -s 2
--then subdivide --levels 1``).  Each step is parsed once per run into its options
(:mod:`shapeflow.commands`, the grammar and the options the command line uses) and runs
the command's own function on every file, so a batch's output equals the single-file
command's.
"""

from __future__ import annotations

import hashlib
import json
import os
import shlex
from dataclasses import dataclass
from typing import Sequence

from ..errors import ParameterError

__all__ = ["Operation", "parse_operation", "STEP_COMMANDS", "THEN"]

#: commands a batch can run on each file (``info`` writes nothing)
STEP_COMMANDS = ("flow", "enhance", "smooth", "subdivide", "family", "render", "curvature", "brush")
#: commands whose output is not a mesh another step could read: last in a pipeline only
LAST_ONLY = ("family", "render", "curvature")
#: options that write one more file per run: one path for every file of a batch would collide
SIDE_OUTPUTS = (("image", "--image"), ("weights_out", "--weights-out"))
THEN = "--then"
#: options whose value is a file the steps read: its contents decide the output as much as the option
FILE_OPTIONS = ("--weights", "--sharp-edges", "--creases", "--stroke")


@dataclass(frozen=True)
class Operation:
    """The checked steps of a batch operation: each as typed, ``(command, *options)``, and its
    options object (:mod:`shapeflow.commands`); made by :func:`parse_operation`."""

    steps: tuple[tuple[str, ...], ...]
    options: tuple = ()

    @property
    def text(self) -> str:
        """The operation as typed on the command line."""
        return f" {THEN} ".join(shlex.join(s) for s in self.steps)

    @property
    def last(self) -> str:
        return self.steps[-1][0]

    def output_suffix(self, input_suffix: str, fmt: str | None) -> str:
        """Extension of a file's output: ``--format``, else PNG for render, .npy for curvature,
        a folder ('') for family, else the input's."""
        if self.last == "family":
            return ""
        if fmt:
            return fmt.lower() if fmt.startswith(".") else "." + fmt.lower()
        return {"render": ".png", "curvature": ".npy"}.get(self.last, input_suffix.lower())

    def digest(self, fmt: str | None) -> str:
        """Hash of everything that decides a file's output: the steps, the output format and the
        contents of the files the steps read (``--weights``, ``--sharp-edges``, ``--creases``,
        ``--stroke``): a rerun after such a file changed redoes every output."""
        blob = json.dumps({"steps": self.steps, "format": fmt, "files": self.read_files()}, sort_keys=True).encode()
        return hashlib.sha256(blob).hexdigest()[:16]

    def read_files(self) -> dict[str, str]:
        """SHA-256 of each file an option of the steps names (a ``--weights`` attribute name, which
        is no file, is left out)."""
        out = {}
        for step in self.steps:
            for i, tok in enumerate(step):
                name, eq, value = tok.partition("=")
                if name not in FILE_OPTIONS:
                    continue
                value = value if eq else (step[i + 1] if i + 1 < len(step) else "")
                if value and os.path.isfile(value):
                    h = hashlib.sha256()
                    with open(value, "rb") as f:
                        for block in iter(lambda: f.read(1 << 20), b""):
                            h.update(block)
                    out[value] = h.hexdigest()
        return out


def _split(tokens: list[str]) -> list[list[str]]:
    steps, cur = [], []
    for t in tokens:
        if t == THEN:
            steps.append(cur)
            cur = []
        else:
            cur.append(t)
    steps.append(cur)
    return steps


def parse_operation(operation: str | Sequence[str] | Operation, *, fmt: str | None = None) -> Operation:
    """Check an operation (a string, an argv list, or an :class:`Operation`) before any work.

    Every step is parsed with the commands' own grammar into its options object, whose values are
    checked as it is made, so an unknown option or a bad value is reported now, naming the step;
    options that write a side file per run (``--image``, ``--weights-out``) are refused.
    """
    if isinstance(operation, Operation):
        steps = [list(s) for s in operation.steps]
    elif isinstance(operation, str):
        try:
            steps = _split(shlex.split(operation))
        except ValueError as exc:
            raise ParameterError(f"operation {operation!r}: {exc}") from None
    else:
        steps = _split([str(t) for t in operation])
    if not steps or not steps[0]:
        raise ParameterError(f"no OPERATION given; one of: {', '.join(STEP_COMMANDS)} with its options "
                             f"(several joined by {THEN})")
    from ..commands import operations_parser, options_from

    parser = operations_parser()
    options = []
    for i, step in enumerate(steps):
        where = f"step {i + 1} of the operation" if len(steps) > 1 else "the operation"
        if not step:
            raise ParameterError(f"{where} is empty (two {THEN} in a row, or one at an end)")
        if step[0] not in STEP_COMMANDS:
            raise ParameterError(f"{where}: {step[0]!r} is not a command a batch runs; "
                                 f"use one of {', '.join(STEP_COMMANDS)}")
        if step[0] in LAST_ONLY and i < len(steps) - 1:
            raise ParameterError(f"{where}: {step[0]} writes no mesh for a next step; put it last")
        try:
            args = parser.parse_args(_step_argv(step, fmt))
        except ParameterError as exc:
            msg = str(exc).split(": ", 1)[-1]
            raise ParameterError(f"{where} ({shlex.join(step)}): {msg} (options of the batch itself, such as "
                                 "--format or --workers, go before INPUTS)") from None
        for attr, flag in SIDE_OUTPUTS:
            if getattr(args, attr, None):
                raise ParameterError(f"{where}: {flag} writes one more file per run; a batch writes one "
                                     "output per file (render the outputs in a second batch)")
        try:
            options.append(options_from(args))
        except ParameterError as exc:
            raise ParameterError(f"{where} ({shlex.join(step)}): {exc}") from None
    return Operation(tuple(tuple(s) for s in steps), tuple(options))


def _step_argv(step: list[str], fmt: str | None) -> list[str]:
    """A step's words as a command line on stand-in paths; a family also redoes the members of an
    interrupted earlier run (``--force``) and writes the batch's ``--format`` unless it names one."""
    cmd, *opts = step
    extra = []
    if cmd == "family":
        extra.append("--force")
        if fmt and "--format" not in opts:
            extra += ["--format", fmt.lstrip(".").lower()]
    out = "out" if cmd == "family" else "out" + (f".{fmt.lstrip('.')}" if fmt else ".ply")
    return [cmd, *opts, *extra, "in.ply", out]


def run_steps(op: Operation, source: str, output: str, workdir: str, report) -> None:
    """Run every step on ``source``, telling ``report``; intermediate meshes go to ``workdir`` (input's format)."""
    from ..commands import run

    cur = source
    ext = os.path.splitext(source)[1] or ".ply"
    for i, options in enumerate(op.options):
        out = output if i == len(op.options) - 1 else os.path.join(workdir, f"step{i + 1}{ext}")
        run(options, cur, out, report)
        cur = out
