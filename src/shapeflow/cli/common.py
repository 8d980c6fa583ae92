"""The command line's side of the commands: every line on stderr, a progress bar on a terminal."""

from __future__ import annotations

import sys

from ..commands.common import load_mesh
from ..commands.report import Reporter


def eprint(*a, **kw) -> None:
    print(*a, file=sys.stderr, **kw)


class Terminal(Reporter):
    """The command line's reporter: messages and warnings are lines on stderr; progress is a tqdm bar
    when stderr is a terminal and tqdm is installed (extra ``progress``)."""

    def message(self, text: str) -> None:
        eprint(text)

    def warning(self, text: str) -> None:
        eprint(text)

    def progress(self, total: int, desc: str):
        return ProgressBar(total, desc)


class ProgressBar:
    """Context manager giving a ``progress(done, total)`` callback that draws a tqdm bar on a
    terminal, or None (no terminal, no tqdm, or less than two steps)."""

    def __init__(self, total: int, desc: str):
        self.total = total
        self.desc = desc
        self.bar = None

    def __enter__(self):
        if self.total < 2 or not sys.stderr.isatty():
            return None
        try:
            from tqdm import tqdm
        except Exception:   # noqa: BLE001 - no bars without a working tqdm
            return None
        self.bar = tqdm(total=self.total, desc=self.desc, unit="it", file=sys.stderr, leave=False)

        def cb(done, total):
            self.bar.update(done - self.bar.n)

        return cb

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False


def load_mesh_arg(arg: str, *, faces: bool = True):
    """A mesh named on the command line (a path or ``example:NAME``); see
    :func:`shapeflow.commands.common.load_mesh`."""
    return load_mesh(arg, Terminal(), faces=faces)
