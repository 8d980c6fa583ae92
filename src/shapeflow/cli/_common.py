"""Helpers shared by the subcommands."""

from __future__ import annotations

import sys


def load_mesh_arg(arg: str):
    """Load a mesh given on the command line: a path or ``example:NAME``."""
    if arg.startswith("example:"):
        from ..examples import load_example

        return load_example(arg.split(":", 1)[1])
    from ..io import load

    return load(arg)


def eprint(*a, **kw) -> None:
    print(*a, file=sys.stderr, **kw)
