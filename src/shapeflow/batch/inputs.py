"""The files of a batch: INPUTS expanded to sources, and where each result goes under OUTDIR.

INPUTS is one of

* a glob, ``**`` recursive (``"scans/**/*.ply"``);
* a folder (every file in it, at any depth, with a mesh extension);
* a manifest: a ``.txt``/``.lst`` file with one path or URL a line (``#`` comments), or a
  ``.csv`` file whose ``path`` column (else its first column) lists them; relative
  entries are relative to the manifest's folder;
* any of these as an fsspec URL (``s3://bucket/scans/**/*.ply``, ``gs://…``,
  ``https://…`` in a manifest), read with fsspec (``pip install 'shapeflow[batch]'``
  and the filesystem's own package, e.g. ``s3fs``);
* a list of such strings (from the Python API).

Outputs mirror the input tree: the path of a source relative to the root of its
INPUTS (the glob's folder part, the folder, or the common folder of a manifest's
entries) is kept under OUTDIR, with the output format's extension.
"""

from __future__ import annotations

import csv
import glob
import io
import os
import posixpath
from dataclasses import dataclass
from typing import Sequence

from ..errors import ParameterError
from ..io.registry import FORMATS

__all__ = ["Job", "expand_inputs", "filesystem", "is_url", "plan_jobs"]

#: file extensions a folder or a glob-free listing picks up (the formats shapeflow reads)
MESH_EXTENSIONS = tuple(sorted(FORMATS))
MANIFEST_EXTENSIONS = (".txt", ".lst", ".list", ".csv")
GLOB_CHARS = "*?["


@dataclass(frozen=True)
class Job:
    """One file of a batch: where it comes from, its path relative to its INPUTS root, where it goes."""

    source: str
    relative: str
    output: str


def is_url(text: str) -> bool:
    """``proto://...`` other than ``file://`` (which is read as a local path)."""
    head, sep, _ = text.partition("://")
    return bool(sep) and head.isidentifier() and head.lower() != "file"


def _local(text: str) -> str:
    return text[len("file://"):] if text.lower().startswith("file://") else text


def filesystem(url: str):
    """``(fs, path)`` of an fsspec URL (ImportError naming the extra without fsspec)."""
    try:
        import fsspec
    except Exception as exc:   # not installed, or installed and broken
        from ..errors import OptionalDependencyError

        raise OptionalDependencyError("fsspec", "batch", f"reading {url!r}", exc) from None
    try:
        return fsspec.core.url_to_fs(url)
    except (ImportError, ValueError) as exc:
        raise ParameterError(f"INPUTS {url!r}: {exc}") from None


def _glob_root(pattern: str, sep: str) -> str:
    parts = pattern.split(sep)
    keep = []
    for part in parts[:-1]:
        if any(c in part for c in GLOB_CHARS):
            break
        keep.append(part)
    return sep.join(keep)


def _is_mesh(name: str) -> bool:
    return os.path.splitext(name)[1].lower() in FORMATS


def _expand_local(arg: str) -> tuple[list[str], str]:
    """(sources, root) of one local INPUTS string."""
    path = _local(arg)
    if any(c in path for c in GLOB_CHARS):
        found = sorted(p for p in glob.glob(path, recursive=True) if os.path.isfile(p))
        return found, _glob_root(path, os.sep) or "."
    if os.path.isdir(path):
        found = sorted(os.path.join(d, f) for d, _, files in os.walk(path) for f in files if _is_mesh(f))
        return found, path
    if os.path.isfile(path) and os.path.splitext(path)[1].lower() in MANIFEST_EXTENSIONS:
        with open(path, "rb") as f:
            entries = _manifest_entries(f.read(), path)
        base = os.path.dirname(os.path.abspath(path))
        found = [e if is_url(e) else os.path.normpath(os.path.join(base, _local(e))) for e in entries]
        local = [e for e in found if not is_url(e)]
        root = os.path.commonpath([os.path.dirname(e) for e in local]) if local else base
        return found, root
    if os.path.isfile(path):
        return [path], os.path.dirname(path) or "."
    raise ParameterError(f"INPUTS {arg!r}: no such file, folder or glob match")


def _manifest_entries(data: bytes, name: str) -> list[str]:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ParameterError(f"manifest {name!r} is not UTF-8 text") from None
    if name.lower().endswith(".csv"):
        rows = list(csv.reader(io.StringIO(text)))
        if not rows:
            return []
        header = [h.strip().lower() for h in rows[0]]
        col = header.index("path") if "path" in header else 0
        body = rows[1:] if "path" in header else rows
        return [r[col].strip() for r in body if len(r) > col and r[col].strip()]
    lines = (ln.strip() for ln in text.splitlines())
    return [ln for ln in lines if ln and not ln.startswith("#")]


def _expand_url(arg: str) -> tuple[list[str], str]:
    fs, path = filesystem(arg)
    proto = arg.split("://", 1)[0]

    def url(p: str) -> str:
        return fs.unstrip_protocol(p) if hasattr(fs, "unstrip_protocol") else f"{proto}://{p}"

    if any(c in path for c in GLOB_CHARS):
        found = sorted(p for p in fs.glob(path) if fs.isfile(p))
        return [url(p) for p in found], url(_glob_root(path, "/"))
    if fs.isdir(path):
        return [url(p) for p in sorted(fs.find(path)) if _is_mesh(p)], url(path)
    if os.path.splitext(path)[1].lower() in MANIFEST_EXTENSIONS:
        with fs.open(path, "rb") as f:
            entries = _manifest_entries(f.read(), arg)
        base = posixpath.dirname(path)
        found = [e if "://" in e else url(posixpath.normpath(posixpath.join(base, e))) for e in entries]
        return found, url(base)
    if fs.isfile(path):
        return [arg], url(posixpath.dirname(path))
    raise ParameterError(f"INPUTS {arg!r}: no such file, folder or glob match")


def _relative(source: str, root: str) -> str:
    if is_url(source):
        rel = source[len(root):].lstrip("/") if source.startswith(root) else source.split("://", 1)[1]
        return rel
    rel = os.path.relpath(source, root)
    if rel.startswith(".."):      # outside the root (a manifest entry elsewhere): keep its name only
        rel = os.path.basename(source)
    return rel.replace(os.sep, "/")


def expand_inputs(inputs: str | Sequence[str]) -> list[tuple[str, str]]:
    """``(source, relative path)`` of every file INPUTS names, in a stable order, no repeats."""
    args = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    if not args:
        raise ParameterError("INPUTS is empty")
    out: dict[str, str] = {}
    for arg in args:
        arg = os.fspath(arg)
        sources, root = _expand_url(arg) if is_url(arg) else _expand_local(arg)
        for s in sources:
            out.setdefault(s, _relative(s, root))
    return list(out.items())


def output_name(relative: str, suffix: str | None) -> str:
    """The output's path relative to OUTDIR: the input's, with ``suffix`` ('' for a folder)."""
    stem, ext = posixpath.splitext(relative)
    return stem + (ext if suffix is None else suffix)


def plan_jobs(inputs, outdir: str, suffix_for) -> list[Job]:
    """The jobs of a batch; ``suffix_for(input_suffix)`` gives the output's extension.

    Two inputs that would write the same output, or an output that is its own input, are
    refused before any work.
    """
    jobs: list[Job] = []
    seen: dict[str, str] = {}
    for source, rel in expand_inputs(inputs):
        out = os.path.join(outdir, *output_name(rel, suffix_for(posixpath.splitext(rel)[1])).split("/"))
        key = os.path.normcase(os.path.abspath(out))
        if key in seen:
            raise ParameterError(f"{seen[key]!r} and {source!r} would both write {out!r}; "
                                 "give --format or separate batches")
        if not is_url(source) and os.path.abspath(source) == os.path.abspath(out):
            raise ParameterError(f"the output of {source!r} would overwrite it; choose another OUTDIR")
        seen[key] = source
        jobs.append(Job(source, rel, out))
    return jobs
