"""The batch driver: plan the files, skip the finished ones, run the rest on Dask, record every outcome.

Engine: Dask's distributed scheduler.  Without a client or a scheduler address,
:func:`run` starts a ``distributed.LocalCluster`` of worker processes sized to the
cores this process may use, one thread each (each file runs with shapeflow's own
threads at 1, so nothing oversubscribes).  Its scheduler retries a file once when
its worker dies (``retries``) and never holds a second file on a busy worker
(``worker-saturation`` 1.0), so a worker's death counts only against the file it
was running.  With ``scheduler="tcp://host:8786"`` or ``client=`` an existing
cluster is used as it is configured (its ``allowed-failures`` decides the
retries there); its workers must import shapeflow and see INPUTS and OUTDIR.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import itertools
import os
import shutil
import time
from typing import Callable, Sequence

from .. import params
from ..errors import ParameterError
from .cluster import deferred_signals, distributed_module, local_cluster
from .inputs import filesystem, is_url, plan
from .manifest import MANIFEST_NAME, STATE_DIR, Manifest, input_stamp
from .operation import Operation, parse_operation
from .paths import OutsideOutdir, confine
from .progress import Progress
from .report import BatchReport
from .task import WORK_PREFIX, ended_reason, failed_record, run_task

__all__ = ["run", "local_cluster"]

#: fsspec protocols whose files only this process sees: the driver reads them and sends the bytes
PROCESS_LOCAL = ("memory",)


def _client(client, scheduler: str | None, workers: int | None, max_memory, retries: int, dashboard: bool,
            log: str | None = None):
    """(client, things to close) for the run."""
    if client is not None:
        return client, []
    distributed = distributed_module()
    if scheduler is not None:
        try:
            c = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ParameterError(f"--scheduler {scheduler!r}: cannot reach the scheduler ({exc})") from None
        return c, [c]
    cluster, c = local_cluster(workers, max_memory=max_memory, retries=retries, dashboard=dashboard, log=log)
    return c, [c, cluster]


def _check(workers, timeout, max_memory, retries) -> None:
    if workers is not None:
        params.integer("workers", workers, lo=1, hi=4096)
    if timeout is not None and not params.number("timeout", timeout) > 0:
        raise ParameterError(f"timeout must be > 0 seconds, got {timeout!r}")
    if max_memory is not None:
        params.integer("max_memory", max_memory, lo=1)
    params.integer("retries", retries, lo=0, hi=100)


def _outcome(fut, job, marker: str) -> dict:
    """The record of a finished future, whatever ended it."""
    try:
        return fut.result()
    except Exception as exc:   # the task itself never raises: this is the engine's word
        from distributed import KilledWorker

        if isinstance(exc, KilledWorker):
            reason = ended_reason(marker)
            if reason is not None:
                return failed_record(job.source, job.output, reason)
            n = exc.args[2] + 1 if len(exc.args) > 2 else "several"
            return failed_record(job.source, job.output, f"its worker process died {n} times while processing "
                                                         "it (out of memory, a crash, or killed)")
        return failed_record(job.source, job.output, f"{type(exc).__name__}: {exc}")


def run(inputs: str | Sequence[str], outdir: str, operation: str | Sequence[str] | Operation, *,
        client=None, scheduler: str | None = None, workers: int | None = None, format: str | None = None,
        force: bool = False, timeout: float | None = None, max_memory: int | None = None, retries: int = 1,
        progress: bool | None = None, progress_interval: float = 10.0, dashboard: bool = True,
        on_start: Callable[[dict], None] | None = None,
        on_notice: Callable[[str], None] | None = None) -> BatchReport:
    """Run an operation on every file of INPUTS, writing results under OUTDIR; returns a report.

    Parameters
    ----------
    inputs : str or list of str
        A glob (``**`` recursive), a folder, a manifest (.txt/.csv of paths or URLs), or
        fsspec URLs of these (:mod:`shapeflow.batch.inputs`).
    outdir : str
        Where outputs go, mirroring the input tree; it also holds the manifest
        ``shapeflow-batch.jsonl`` (:mod:`shapeflow.batch.manifest`).  Nothing is written
        outside it (:mod:`shapeflow.batch.paths`); it is made only once INPUTS is found.
    operation : str or list of str
        A single-file command with its options, without input and output
        (``"enhance --strength 50"``), or several joined by ``--then``.
    client : distributed.Client, optional
        Run on this client's cluster.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``).
    workers : int, optional
        Worker processes of the local cluster (default: the cores this process may use).
    format : str, optional
        Output format (``"ply"``...); default the input's.
    force : bool
        Redo files already done with the same parameters.
    timeout : float, optional
        Seconds a file may run; after that its worker process is restarted and the file fails.
    max_memory : int, optional
        Bytes a worker process may use for a file: a file whose estimate is over fails at once,
        one that goes over has its worker restarted and fails.
    retries : int
        Further attempts after a file's worker died (local cluster; default 1).
    progress : bool, optional
        False: none.  Otherwise a tqdm bar when stderr is a terminal, else a line every
        ``progress_interval`` seconds (:mod:`shapeflow.batch.progress`).
    progress_interval : float
        Seconds between two progress lines off a terminal (default 10).
    on_start : callable(dict), optional
        Called once the cluster runs, with ``files``, ``todo``, ``skipped``, ``workers`` and
        ``dashboard`` (its link or None).
    on_notice : callable(str), optional
        Called, before any file is processed, with each thing the run has to say: OUTDIR left
        out of INPUTS, damaged manifest lines skipped, how many files done before are done
        again and why.  They are also in ``report.notices``.

    Returns
    -------
    BatchReport
    """
    _check(workers, timeout, max_memory, retries)
    params.number("progress_interval", progress_interval)
    if not progress_interval > 0:
        raise ParameterError(f"progress_interval must be > 0 seconds, got {progress_interval!r}")
    op = parse_operation(operation, fmt=format)
    outdir = os.fspath(outdir)
    if not outdir or "\0" in outdir:
        raise ParameterError(f"OUTDIR {outdir!r} is not a folder name")
    digest = op.digest(format)
    t0 = time.perf_counter()
    report = BatchReport(manifest=os.path.join(outdir, MANIFEST_NAME))

    def notice(text: str) -> None:
        report.notices.append(text)
        if on_notice is not None:
            on_notice(text)

    planned = plan(inputs, outdir, lambda ext: op.output_suffix(ext, format))   # nothing made before this
    # a first batch into OUTDIR (no manifest, no batch folder yet) finds no output of its own there
    first = not any(os.path.lexists(os.path.join(outdir, n)) for n in (MANIFEST_NAME, STATE_DIR))
    made = _make_folder(outdir)
    try:
        with Manifest(outdir) as manifest:
            for text in planned.notices:
                notice(text)
            found: list[str] = []
            latest = manifest.latest(found)
            for text in found:
                notice(text)
            todo, skipped = _split_done(planned.jobs, latest, digest, force, notice, first=first)
            report.skipped = skipped
            _process(todo, planned.jobs, op, format, digest, timeout, max_memory, manifest, report,
                     (client, scheduler, workers, retries, dashboard), (progress, progress_interval), on_start)
    except BaseException:
        if not report.records:
            _unmake(outdir, made)
        raise
    report.seconds = time.perf_counter() - t0
    return report


def _make_folder(outdir: str) -> list[str]:
    """Make OUTDIR (and missing parents); returns the folders made, deepest first."""
    made = []
    p = os.path.abspath(outdir)
    while not os.path.lexists(p):
        made.append(p)
        p = os.path.dirname(p)
    os.makedirs(outdir, exist_ok=True)
    return made


def _unmake(outdir: str, made: list[str]) -> None:
    """A run that recorded nothing leaves nothing: its empty manifest, its own folder and the
    folders it made go."""
    path = os.path.join(outdir, MANIFEST_NAME)
    with_state = os.path.join(outdir, ".shapeflow-batch")
    try:
        if os.path.isfile(path) and not os.path.islink(path) and os.path.getsize(path) == 0:
            os.remove(path)
    except OSError:
        pass
    if made and os.path.isdir(with_state) and not os.path.islink(with_state):
        shutil.rmtree(with_state, ignore_errors=True)
    for folder in made:
        try:
            os.rmdir(folder)
        except OSError:
            break


def _n(k: int) -> str:
    return f"{k} file{'s' if k != 1 else ''} done before"


def _split_done(jobs, latest: dict, digest: str, force: bool, notice, *, first: bool = False) -> tuple[list, list]:
    """(jobs to do, sources skipped as done before); says how many done before are done again.

    On a ``first`` batch into OUTDIR, a file already at an output's path is someone else's (OUTDIR
    inside INPUTS holding the user's files, say): that file fails, unless ``force``."""
    todo, skipped = [], []
    changed = forced = other = 0
    for j in jobs:
        if first and not force and not j.error and os.path.lexists(j.output):
            j = dataclasses.replace(j, error=f"{j.output} exists and was not written by shapeflow batch: "
                                             "move it away, or give --force to replace it")
            todo.append(j)
            continue
        r = latest.get(j.source)
        if r is None or r["status"] != "done" or j.error:
            todo.append(j)
        elif force:
            forced += 1
            todo.append(j)
        elif r["params"] != digest:
            changed += 1
            todo.append(j)
        elif r["output"] != j.output or r["input_stamp"] != input_stamp(j.source) or not os.path.exists(j.output):
            other += 1
            todo.append(j)
        else:
            skipped.append(j.source)
    if forced:
        notice(f"--force: {_n(forced)} will be done again")
    if changed:
        notice(f"parameters (or a file they name) changed since the last run: {_n(changed)} will be done again")
    if other:
        notice(f"{_n(other)} will be done again: input changed or output missing")
    return todo, skipped


def _process(todo, jobs, op, fmt, digest, timeout, max_memory, manifest, report, where, show, on_start) -> None:
    """Record the jobs that cannot run, run the rest on the cluster (started here when needed)."""
    client, scheduler, workers, retries, dashboard = where
    bad = [j for j in todo if j.error]
    todo = [j for j in todo if not j.error]
    info = {"files": len(jobs), "todo": len(todo) + len(bad), "skipped": len(report.skipped), "workers": 0,
            "dashboard": None}
    if not todo:
        if on_start is not None:
            on_start(info)
        for j in bad:
            _record(failed_record(j.source, j.output or None, j.error), j, digest, manifest, report)
        return
    log = confine(manifest.outdir, os.path.join(manifest.state, "workers.log"), "the workers' log")
    c, owned = None, []
    try:
        with deferred_signals():
            with open(log, "wb"):
                pass
            c, owned = _client(client, scheduler, workers, max_memory, retries, dashboard, log)
        report.workers = sum(c.nthreads().values()) or (workers or 1)
        report.dashboard = _dashboard(c, local=len(owned) == 2)
        if on_start is not None:
            on_start({**info, "workers": report.workers, "dashboard": report.dashboard})
        for j in bad:
            _record(failed_record(j.source, j.output or None, j.error), j, digest, manifest, report)
        _drive(c, todo, op, fmt, digest, timeout, max_memory, manifest, report, show)
    except KeyboardInterrupt:
        report.interrupted = True
    finally:
        with deferred_signals():
            for thing in owned:
                try:
                    thing.close()
                except Exception:   # closing a cluster that already lost its workers: nothing to keep
                    pass
        shutil.rmtree(os.path.join(manifest.state, "ended"), ignore_errors=True)
        _sweep_work_folders(todo, manifest.outdir)


def _record(rec: dict, job, digest: str, manifest, report, bar=None) -> None:
    from .. import __version__

    rec.update(params=digest, input_stamp=input_stamp(job.source), shapeflow=__version__,
               finished=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
    manifest.append(rec)
    report.records.append(rec)
    if bar is not None:
        bar.update(rec)


def _sweep_work_folders(jobs, outdir: str) -> None:
    """Remove the work folders a file's task leaves beside its output when its worker process ended
    mid-file (every task of this run is over, and OUTDIR's lock keeps other batches out)."""
    for folder in {os.path.dirname(os.path.abspath(j.output)) for j in jobs}:
        try:
            names = os.listdir(confine(outdir, folder, "folder"))
        except (OSError, OutsideOutdir):
            continue
        for name in names:
            if name.startswith(WORK_PREFIX):
                shutil.rmtree(os.path.join(folder, name), ignore_errors=True)


def _dashboard(c, local: bool) -> str | None:
    """The dashboard's link when there is one (a local cluster's needs bokeh here)."""
    import importlib.util

    if local and not importlib.util.find_spec("bokeh"):
        return None
    try:
        return c.dashboard_link if c.scheduler_info().get("services", {}).get("dashboard") else None
    except Exception:   # no scheduler information: nothing to print
        return None


def _read_here(source: str) -> bytes | None:
    """The bytes of a URL that only this process can read (``memory://``), else None."""
    if not is_url(source) or source.split("://", 1)[0].lower() not in PROCESS_LOCAL:
        return None
    try:
        fs, path = filesystem(source)
        return fs.cat_file(path)
    except Exception:    # the worker's own attempt says what is wrong with it
        return None


def _drive(c, todo, op, fmt, digest, timeout, max_memory, manifest, report, show) -> None:
    """Submit the files in a sliding window, record each as it finishes."""
    from distributed import as_completed

    ended = confine(manifest.outdir, os.path.join(manifest.state, "ended"), "the batch's folder")
    os.makedirs(ended, exist_ok=True)
    window = max(32, 8 * report.workers)
    meta = {}

    def submit(job):
        key = "shapeflow-batch-" + hashlib.sha256(f"{job.source}\0{digest}".encode()).hexdigest()[:24]
        marker = os.path.join(ended, key + ".json")
        if os.path.exists(marker):
            os.remove(marker)
        fut = c.submit(run_task, job.source, job.output, op, fmt, marker, timeout, max_memory, manifest.outdir,
                       _read_here(job.source), key=key, pure=False)
        meta[fut.key] = (job, marker)
        return fut

    pending = iter(todo)
    bar = Progress(len(todo), show[0], show[1])
    try:
        ac = as_completed([submit(j) for j in itertools.islice(pending, window)])
        for fut in ac:
            job, marker = meta.pop(fut.key)
            rec = _outcome(fut, job, marker)
            fut.release()
            _record(rec, job, digest, manifest, report, bar)
            nxt = next(pending, None)
            if nxt is not None:
                ac.add(submit(nxt))
    finally:
        bar.close()
