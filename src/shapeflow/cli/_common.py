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


def resolve_output(input_arg: str, output: str, force: bool) -> str:
    """Refuse to overwrite the input file unless forced."""
    import os

    from ..errors import ParameterError

    if not input_arg.startswith("example:") and os.path.exists(output) and os.path.exists(input_arg) \
            and os.path.samefile(input_arg, output) and not force:
        raise ParameterError(f"output {output!r} is the input file; pass --force to overwrite it")
    return output


def save_mesh(path: str, mesh) -> None:
    """Write atomically (the I/O layer writes a temporary file, then renames it)."""
    from ..io import save

    save(path, mesh)


class progress_callback:
    """Context manager giving a ``progress(done, total)`` callback: a tqdm bar on a
    terminal when tqdm is installed (extra ``progress``), else nothing."""

    def __init__(self, total: int, desc: str, quiet: bool = False):
        self.total = total
        self.desc = desc
        self.quiet = quiet
        self.bar = None

    def __enter__(self):
        if self.quiet or self.total < 2 or not sys.stderr.isatty():
            return None
        try:
            from tqdm import tqdm
        except ImportError:
            return None
        self.bar = tqdm(total=self.total, desc=self.desc, unit="it", file=sys.stderr, leave=False)

        def cb(done, total):
            self.bar.update(done - self.bar.n)

        return cb

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
        return False
