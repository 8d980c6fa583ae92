"""Where a batch may write: every path it writes is proven inside OUTDIR by :func:`confine`.

The results, the manifest, the batch's own folder (lock, reasons of ended workers),
the work folders beside each output and the files in them all pass through
:func:`confine` before anything is created, opened for writing or removed: the
path, normalised and with every symbolic link of it resolved, must lie inside
OUTDIR's own real folder.  A name that comes from a source (its path relative to
its INPUTS root, a URL's path) is first made a plain relative name by
:func:`output_name`: ``\\`` separates like ``/``, a URL's percent-escapes are
decoded, ``.`` segments go, and ``..`` removes the segment before it without ever
climbing above the root (RFC 3986 §5.2.4), so ``http://h/a/../../x.ply``,
``%2e%2e/x.ply`` and ``..\\x.ply`` all name ``x.ply`` under OUTDIR.
"""

from __future__ import annotations

import os
from urllib.parse import unquote

from ..errors import ParameterError

__all__ = ["OutsideOutdir", "output_name", "confine", "NAME_MAX", "PATH_MAX"]

#: bytes of one file name, and of a whole path, that Linux file systems take
NAME_MAX = 255
PATH_MAX = 4096


class OutsideOutdir(ParameterError):
    """A path a batch would write is not inside OUTDIR, or cannot be a file name there."""


def output_name(relative: str, *, url: bool = False) -> str:
    """A source's path relative to its INPUTS root as a safe relative name (``"a/b.ply"``).

    ``url``: the name comes from a URL, whose percent-escapes are decoded first (``%2e`` is a
    dot, ``%2f`` a separator).  Raises :class:`OutsideOutdir` for a name with a NUL character
    or with nothing left once normalised.
    """
    text = unquote(relative, errors="replace") if url else relative
    if "\0" in text:
        raise OutsideOutdir(f"{relative!r}: a file name cannot hold a NUL character")
    parts: list[str] = []
    for seg in text.replace("\\", "/").split("/"):
        if seg in ("", "."):
            continue
        if seg == "..":
            if parts:
                parts.pop()
            continue
        parts.append(seg)
    if not parts:
        raise OutsideOutdir(f"{relative!r}: no file name left once '.', '..' and empty parts are removed")
    return "/".join(parts)


def _inside(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


def confine(outdir: str, path: str, what: str = "output") -> str:
    """``path`` (a file or folder under ``outdir``, as file operations take it: absolute or relative to
    the current folder, like ``outdir`` itself), proven inside OUTDIR; else :class:`OutsideOutdir`.

    Proven means: no NUL character; no part longer than :data:`NAME_MAX` bytes and the whole
    under :data:`PATH_MAX`; lexically under ``outdir`` (``..`` cannot leave it); and with every
    symbolic link along it resolved, the path itself included, still inside OUTDIR's real
    folder (a folder or file that is a link leading out of OUTDIR is refused).
    """
    if "\0" in path or "\0" in outdir:
        raise OutsideOutdir(f"{what} {path!r}: a path cannot hold a NUL character")
    base = os.path.abspath(outdir)
    full = os.path.abspath(path)
    rel = os.path.relpath(full, base)
    if rel == os.pardir or rel.startswith(os.pardir + os.sep) or os.path.isabs(rel):
        raise OutsideOutdir(f"{what} {path!r} is outside OUTDIR {outdir!r}")
    longest = max((len(os.fsencode(p)) for p in rel.split(os.sep)), default=0)
    if longest > NAME_MAX:
        raise OutsideOutdir(f"{what} {path!r}: a name of {longest} bytes is longer than the {NAME_MAX} "
                            "a file system takes")
    if len(os.fsencode(full)) >= PATH_MAX:
        raise OutsideOutdir(f"{what} {path!r}: the path is {len(os.fsencode(full))} bytes, over the "
                            f"{PATH_MAX - 1} a file system takes")
    real_base = os.path.realpath(base)
    real = os.path.realpath(full)
    if not _inside(real, real_base):
        raise OutsideOutdir(f"{what} {path!r} would be written outside OUTDIR {outdir!r}: it leads to "
                            f"{real!r} through a symbolic link")
    return path
