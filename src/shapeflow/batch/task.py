"""One file of a batch: :func:`process_file`, the picklable per-file function.

It never raises for a bad file: every outcome is a record (a dict ready for the
manifest) whose ``status`` is ``"done"`` or ``"failed"`` with the error's message.
Usable from any runner of Python functions::

    from multiprocessing import Pool
    from shapeflow.batch import process_file

    with Pool(2) as pool:
        records = pool.starmap(process_file, [("in/a.obj", "out/a.obj", "enhance --strength 50"),
                                              ("in/b.ply", "out/b.ply", "enhance --strength 50")])

The commands tell their messages to a :class:`~shapeflow.commands.report.Collector` of the file's
own.  Thread model: one file per process at a time (the runners above, Dask workers with one
thread each).  The library's warnings are recorded with :func:`warnings.catch_warnings`,
which is process-wide, so two calls in threads of one process would mix their warnings.
"""

from __future__ import annotations

import contextlib
import json
import os
import posixpath
import shutil
import tempfile
import threading
import time
import warnings
from typing import Callable

from .. import accel
from ..errors import MeshError, OptionalDependencyError, ShapeflowError
from .estimate import estimate_peak_bytes, header_vertices
from .inputs import is_url
from .operation import Operation, parse_operation, run_steps
from .paths import NAME_MAX, confine

__all__ = ["process_file", "run_task", "jsonable", "failed_record", "ended_reason", "WORK_PREFIX"]

#: name prefix of the work folder a file's task makes beside its output (removed when it ends)
WORK_PREFIX = ".shapeflow-batch-"


def _rss() -> int:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        import psutil

        return int(psutil.Process().memory_info().rss)


class RssSampler:
    """The peak resident memory of this process while the block runs (sampled every 20 ms);
    ``on_exceed(rss)`` is called from the sampling thread if it passes ``limit``."""

    def __init__(self, limit: int | None = None, on_exceed: Callable[[int], None] | None = None):
        self.limit, self.on_exceed = limit, on_exceed
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="shapeflow-batch-rss", daemon=True)

    def _run(self):
        while True:
            rss = _rss()
            self.peak = max(self.peak, rss)
            if self.limit is not None and rss > self.limit and self.on_exceed is not None:
                self.on_exceed(rss)
            if self._stop.wait(0.02):
                return

    def __enter__(self):
        self.peak = _rss()
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, _rss())
        return False


def jsonable(obj):
    """A report (dataclass, numpy values) as plain JSON types; per-vertex arrays are left out."""
    import dataclasses

    import numpy as np

    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if not (isinstance(getattr(obj, f.name), np.ndarray) and getattr(obj, f.name).size > 64)}
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _fetch(url: str, directory: str, data: bytes | None = None) -> str:
    """The input, downloaded (or ``data`` written) into a folder of its own inside the work folder."""
    from .inputs import filesystem

    folder = os.path.join(directory, "input")
    os.mkdir(folder)
    name = posixpath.basename(url.split("://", 1)[-1].split("?", 1)[0].rstrip("/")) or "input"
    local = os.path.join(folder, name if "\0" not in name and len(os.fsencode(name)) <= NAME_MAX else "input")
    if data is not None:
        with open(local, "wb") as f:
            f.write(data)
        return local
    fs, path = filesystem(url)
    fs.get_file(path, local)
    return local


def _error_text(exc: BaseException) -> str:
    if isinstance(exc, (ShapeflowError, OptionalDependencyError)):
        return str(exc)
    if isinstance(exc, MemoryError):
        return "out of memory"
    if isinstance(exc, OSError):
        where = f" '{exc.filename}'" if getattr(exc, "filename", None) else ""
        return f"OSError:{where} {exc.strerror or exc}"
    if isinstance(exc, RecursionError):
        return "input nested too deeply"
    msg = str(exc).splitlines()[0][:300] if str(exc) else ""
    return f"internal error: {type(exc).__name__}: {msg}"


def process_file(source: str, output: str, operation: str | list | Operation, *, format: str | None = None,
                 max_memory: int | None = None, threads: int | str = 1,
                 sampler: RssSampler | None = None, outdir: str | None = None, data: bytes | None = None) -> dict:
    """Run a batch operation on one file and write its output atomically; returns its record.

    Parameters
    ----------
    source : str
        A local path or an fsspec URL.
    output : str
        The output file (a folder for ``family``); its parent is created.
    operation : str, list of str or Operation
        As after ``shapeflow batch INPUTS OUTDIR`` (``"enhance --strength 50"``).
    format : str, optional
        The output format (passed to ``family``; otherwise ``output``'s extension decides).
    max_memory : int, optional
        Bytes: a file whose estimated peak (:mod:`shapeflow.batch.estimate`) is larger fails
        at once with the estimate.
    threads : int or "auto"
        Threads of shapeflow's compiled kernels (1: one file per core, no oversubscription).
    outdir : str, optional
        The output and everything made for it (its folder, the work folder) must lie inside
        this folder (:func:`shapeflow.batch.paths.confine`), or the file fails before anything
        is written.
    data : bytes, optional
        The source's bytes, read by the caller (a URL of a filesystem this process cannot see,
        such as ``memory://``); ``source`` then only names it.

    Returns
    -------
    dict
        ``input``, ``output``, ``status`` ("done" or "failed"), ``error``, ``seconds``,
        ``peak_rss`` (bytes, this process's peak resident memory while the file ran),
        ``vertices``, ``faces``, ``report`` (the flow or family report) and ``messages``
        (what the command would have printed, warnings included).  Messages and errors name
        ``source`` and ``output``, never the work folder's files.
    """
    op = operation if isinstance(operation, Operation) and len(operation.options) == len(operation.steps) \
        else parse_operation(operation, fmt=format)
    t0 = time.perf_counter()
    rec = failed_record(source, output)
    own = sampler is None
    sampler = sampler or RssSampler()
    names: dict[str, str] = {}
    work = None
    try:
        parent = os.path.dirname(os.path.abspath(output))
        if outdir is not None:
            confine(outdir, output)
        os.makedirs(parent, exist_ok=True)
        work = tempfile.mkdtemp(prefix=WORK_PREFIX, dir=parent)
        if outdir is not None:
            confine(outdir, work, "work folder")
        with sampler if own else contextlib.nullcontext():
            _run_one(op, source, output, work, max_memory, threads, rec, names, data)
    except BaseException as exc:   # a file's failure is its record; Ctrl-C and exits still end the run
        rec["error"] = _final_names(_error_text(exc), names, work)
        if not isinstance(exc, Exception):
            raise
    finally:
        if work is not None:
            shutil.rmtree(work, ignore_errors=True)
        rec["seconds"] = time.perf_counter() - t0
        rec["peak_rss"] = sampler.peak
    return rec


def _final_names(text: str, names: dict[str, str], work: str | None) -> str:
    """``text`` naming the source and the output where it named their stand-ins in the work folder."""
    for temp, final in sorted(names.items(), key=lambda kv: -len(kv[0])):
        text = text.replace(temp, final)
    return text.replace(work + os.sep, "") if work else text


def _run_one(op: Operation, source: str, output: str, work: str, max_memory, threads, rec: dict,
             names: dict[str, str], data: bytes | None) -> None:
    from ..commands import Collector

    if "\0" in source:
        raise MeshError(f"{source!r}: a file name cannot hold a NUL character")
    local = _fetch(source, work, data) if is_url(source) or data is not None else source
    names[local] = source
    if not os.path.exists(local):
        raise FileNotFoundError(2, "No such file or directory", source)
    if max_memory is not None:
        n = header_vertices(local)
        est = estimate_peak_bytes(n, op.options) + _rss()
        if est > max_memory:
            rec["vertices"] = n
            rec["error"] = (f"estimated peak memory {est / 2**30:.2f} GiB ({n} vertices declared or estimated) "
                            f"is over --max-memory {max_memory / 2**30:.2f} GiB")
            return
    final = os.path.join(work, os.path.basename(output.rstrip(os.sep)))
    names[final] = output
    said = Collector()
    with warnings.catch_warnings(record=True) as caught, accel.use(threads=threads):
        warnings.simplefilter("always")
        try:
            run_steps(op, local, final, work, said)
        finally:
            rec["messages"] = [_final_names(m, names, work) for m in said.messages]
            rec["messages"] += [_final_names(f"warning: {w.message}", names, work) for w in caught]
            rec["vertices"] = said.facts.get("vertices")
            rec["faces"] = said.facts.get("faces")
            rep = said.facts.get("report", said.facts.get("reports"))
            rec["report"] = jsonable(rep) if rep is not None else None
    if os.path.islink(output):
        os.remove(output)              # a link in OUTDIR is replaced, never followed
    elif os.path.isdir(final) and os.path.isdir(output):
        shutil.rmtree(output)
    os.replace(final, output)
    rec["status"] = "done"


def failed_record(source: str, output: str, error: str | None = None) -> dict:
    """A file's record before it has done anything: status "failed" with ``error``."""
    return {"input": source, "output": output, "status": "failed", "error": error, "seconds": 0.0,
            "peak_rss": None, "vertices": None, "faces": None, "report": None, "messages": []}


def ended_reason(marker: str) -> str | None:
    """Why a worker ended a file's task (see :func:`run_task`), or None when none did."""
    if not os.path.exists(marker):
        return None
    try:
        with open(marker) as f:
            return json.load(f)["reason"]
    except (OSError, ValueError, KeyError):
        return "its worker ended while processing it"


def _die(marker: str, reason: str) -> None:
    """Record why this worker process ends, then end it at once (its nanny starts a new one)."""
    try:
        tmp = marker + f".{os.getpid()}.tmp"
        with open(tmp, "w") as f:
            json.dump({"reason": reason}, f)
        os.replace(tmp, marker)
    finally:
        os._exit(70)


def run_task(source: str, output: str, op: Operation, fmt: str | None, marker: str,
             timeout: float | None = None, max_memory: int | None = None, outdir: str | None = None,
             data: bytes | None = None) -> dict:
    """The Dask task of one file: :func:`process_file` with the per-file limits enforced.

    A file still running after ``timeout`` seconds, or whose process passes ``max_memory``
    bytes, ends its worker process (nothing else can stop a running NumPy call); the reason
    goes to ``marker`` first, so the retry the scheduler then makes fails at once with it.
    """
    reason = ended_reason(marker)
    if reason is not None:
        return failed_record(source, output, reason)
    timer = None
    if timeout:
        timer = threading.Timer(timeout, _die, (marker, f"timed out after {timeout:g} s (its worker was restarted)"))
        timer.daemon = True
        timer.start()
    limit_hit = None
    if max_memory:
        def limit_hit(rss):
            _die(marker, f"used {rss / 2**30:.2f} GiB, over --max-memory {max_memory / 2**30:.2f} GiB "
                         "(its worker was restarted)")
    sampler = RssSampler(limit=max_memory, on_exceed=limit_hit)
    try:
        with sampler:
            return process_file(source, output, op, format=fmt, max_memory=max_memory, threads=1,
                                sampler=sampler, outdir=outdir, data=data)
    finally:
        if timer is not None:
            timer.cancel()
