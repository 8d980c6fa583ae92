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
import fnmatch
import heapq
import io
import os
import posixpath
from dataclasses import dataclass
from typing import Iterator, Sequence
from urllib.parse import unquote

from ..errors import ParameterError
from ..io.registry import FORMATS
from .paths import confine, output_name

__all__ = ["Job", "Plan", "expand_inputs", "filesystem", "is_url", "plan", "plan_jobs"]

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
    error: str | None = None     #: why there is no output path for it (it fails alone)


def is_url(text: str) -> bool:
    """``proto://...`` other than ``file://`` and ``local://`` (which are read as local paths)."""
    head, sep, _ = text.partition("://")
    return bool(sep) and head.isidentifier() and head.lower() not in ("file", "local")


def _local(text: str) -> str:
    """A local path from a path, a ``file://`` URL (percent-escapes decoded) or a ``local://`` one."""
    low = text.lower()
    if low.startswith("local://"):
        return text[len("local://"):]
    if not low.startswith("file://"):
        return text
    rest = text[len("file://"):]
    if rest.lower().startswith("localhost/"):
        rest = rest[len("localhost"):]
    return unquote(rest)


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


def _key(path: str):
    """(device, inode) of what ``path`` leads to, or None."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def _direct(path: str) -> bool:
    """``path`` reaches its file through no symbolic link."""
    return os.path.realpath(path) == os.path.abspath(path)


def _walk(top: str, skip: Walk) -> Iterator[tuple[str, str]]:
    """``(path, path relative to top)`` of every file under ``top``.  Symbolic links to folders are
    followed, but each real folder is entered once (a loop of links ends there; folders reached
    without a link come first); a folder in ``skip.folders`` (OUTDIR) is not entered."""
    seen: set = set()
    heap = [(False, "", top)]      # (reached through a link, relative path, path)
    while heap:
        link, rel, folder = heapq.heappop(heap)
        key = _key(folder)
        if key is None or key in seen:
            continue
        seen.add(key)
        if key in skip.folders:
            skip.hit = True
            continue
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for e in entries:
            if not skip.hidden and e.name.startswith("."):
                continue
            r = f"{rel}/{e.name}" if rel else e.name
            try:
                if e.is_dir():
                    if skip.depth is None or r.count("/") + 1 < skip.depth:
                        heapq.heappush(heap, (link or e.is_symlink(), r, e.path))
                elif e.is_file():
                    yield e.path, r
            except OSError:
                continue


@dataclass
class Walk:
    """What a walk leaves out: OUTDIR's folder (``folders``), hidden names, depths past ``depth``."""

    folders: frozenset = frozenset()
    hidden: bool = True
    depth: int | None = None
    hit: bool = False


def _match(segs: list[str], parts: list[str]) -> bool:
    """``parts`` of a relative path against glob segments (``**``: any number of folders)."""
    if not segs:
        return not parts
    if segs[0] == "**":
        return any(_match(segs[1:], parts[k:]) for k in range(len(parts) + 1))
    return (bool(parts) and fnmatch.fnmatchcase(parts[0], segs[0])
            and (not parts[0].startswith(".") or segs[0].startswith(".")) and _match(segs[1:], parts[1:]))


def _expand_local(arg: str, skip: Walk) -> tuple[list[str], str]:
    """(sources, root) of one local INPUTS string."""
    path = _local(arg)
    if any(c in path for c in GLOB_CHARS):
        root = _glob_root(path, os.sep) or (os.sep if path.startswith(os.sep) else "")
        segs = [s for s in path[len(root):].split(os.sep) if s not in ("", ".")]
        if not os.path.isdir(root or "."):
            raise ParameterError(f"INPUTS {arg!r}: no such file, folder or glob match")
        walk = Walk(skip.folders, any(s.startswith(".") for s in segs), None if "**" in segs else len(segs))
        found = sorted(os.path.normpath(p) for p, rel in _walk(root or ".", walk) if _match(segs, rel.split("/")))
        skip.hit |= walk.hit
        return found, root or "."
    if os.path.isdir(path):
        return sorted(p for p, rel in _walk(path, skip) if _is_mesh(p)), path
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
    """The source's path below its INPUTS root, as :func:`~shapeflow.batch.paths.output_name` makes it."""
    if is_url(source):
        rel = source[len(root):] if source.startswith(root.rstrip("/") + "/") else source.split("://", 1)[1]
        return output_name(rel.split("?", 1)[0].split("#", 1)[0], url=True)
    rel = os.path.relpath(source, root)
    if rel.startswith(".."):      # outside the root (a manifest entry elsewhere): keep its name only
        rel = os.path.basename(source)
    return output_name(rel.replace(os.sep, "/"))


@dataclass
class Plan:
    """The jobs of a batch, and what the planning has to say (OUTDIR left out of INPUTS)."""

    jobs: list
    notices: list


def _inputs(inputs, outdir: str | None) -> tuple[list[tuple[str, str | Exception]], list[str]]:
    """``([(source, relative path or the reason there is none)], notices)``; see :func:`plan_jobs`."""
    args = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    if not args:
        raise ParameterError("INPUTS is empty")
    out_key = _key(outdir) if outdir is not None else None
    real_out = os.path.realpath(outdir) if outdir is not None else None
    skip = Walk(frozenset([out_key]) if out_key else frozenset())
    notices = []
    pairs: dict[str, str | Exception] = {}
    by_key: dict = {}
    for arg in args:
        arg = os.fspath(arg)
        sources, root = _expand_url(arg) if is_url(arg) else _expand_local(arg, skip)
        tree = not is_url(arg) and (os.path.isdir(_local(arg)) or any(c in _local(arg) for c in GLOB_CHARS))
        if real_out is not None and tree and os.path.realpath(root) == real_out:
            raise ParameterError(f"OUTDIR {outdir!r} is the INPUTS folder {root!r} itself: the outputs "
                                 "would land among the inputs; choose another OUTDIR")
        if real_out is not None and tree and real_out.startswith(os.path.realpath(root).rstrip(os.sep) + os.sep):
            skip.hit = True
        for s in sources:
            s = s if is_url(s) else _local(s)
            if s in pairs:
                continue
            key = None if is_url(s) else _key(s)
            if key is not None:            # one file reached twice (links): done once, by its real path
                other = by_key.get(key)
                if other is not None:
                    if not _direct(s) or _direct(other):
                        continue
                    del pairs[other]
                by_key[key] = s
            try:
                pairs[s] = _relative(s, root)
            except ParameterError as exc:
                pairs[s] = exc
    if skip.hit:
        notices.append(f"OUTDIR {outdir} is inside INPUTS: its files are not taken as inputs")
    return list(pairs.items()), notices


def expand_inputs(inputs: str | Sequence[str]) -> list[tuple[str, str]]:
    """``(source, relative path)`` of every file INPUTS names, in a stable order, no repeats
    (a file reached twice through symbolic links is listed once)."""
    return [(s, r) for s, r in _inputs(inputs, None)[0] if isinstance(r, str)]


def output_name_of(relative: str, suffix: str | None) -> str:
    """The output's path relative to OUTDIR: the input's, with ``suffix`` ('' for a folder)."""
    stem, ext = posixpath.splitext(relative)
    return stem + (ext if suffix is None else suffix)


def plan(inputs, outdir: str, suffix_for) -> Plan:
    """The jobs of a batch and its notices; ``suffix_for(input_suffix)`` gives the output's extension.

    OUTDIR's own files are never inputs (a notice says so when OUTDIR is inside INPUTS);
    OUTDIR being an INPUTS folder itself, two inputs that would write the same output, or an
    output that is its own input are refused before any work.  A source whose output cannot
    be a path inside OUTDIR (:func:`~shapeflow.batch.paths.confine`) gets a job with its
    ``error`` and fails alone.
    """
    pairs, notices = _inputs(inputs, outdir)
    jobs: list[Job] = []
    seen: dict[str, str] = {}
    local = {os.path.normcase(os.path.realpath(s)): s for s, r in pairs if not is_url(s) and isinstance(r, str)}
    for source, rel in pairs:
        if isinstance(rel, Exception):
            jobs.append(Job(source, "", "", str(rel)))
            continue
        out = os.path.join(outdir, *output_name_of(rel, suffix_for(posixpath.splitext(rel)[1])).split("/"))
        try:
            confine(outdir, out)
        except ParameterError as exc:
            jobs.append(Job(source, rel, out, str(exc)))
            continue
        key = os.path.normcase(os.path.abspath(out))
        if key in seen:
            raise ParameterError(f"{seen[key]!r} and {source!r} would both write {out!r}; "
                                 "give --format or separate batches")
        if not is_url(source) and os.path.abspath(source) == os.path.abspath(out):
            raise ParameterError(f"the output of {source!r} would overwrite it; choose another OUTDIR")
        other = local.get(os.path.normcase(os.path.realpath(out)))
        if other is not None:
            raise ParameterError(f"the output of {source!r} would overwrite the input {other!r}; "
                                 "choose an OUTDIR that holds no input")
        seen[key] = source
        jobs.append(Job(source, rel, out))
    return Plan(jobs, notices)


def plan_jobs(inputs, outdir: str, suffix_for) -> list[Job]:
    """The jobs of :func:`plan` (``suffix_for(input_suffix)`` gives the output's extension)."""
    return plan(inputs, outdir, suffix_for).jobs
