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

import datetime
import hashlib
import itertools
import os
import shutil
import sys
import time
from typing import Callable, Sequence

from .. import params
from ..errors import OptionalDependencyError, ParameterError
from .inputs import plan_jobs
from .manifest import Manifest, input_stamp
from .operation import Operation, parse_operation
from .report import BatchReport
from .task import WORK_PREFIX, ended_reason, failed_record, run_task

__all__ = ["run", "local_cluster"]


def _distributed():
    try:
        import distributed
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("distributed", "batch", "shapeflow batch", exc) from None
    return distributed


def local_cluster(workers: int | None = None, *, max_memory: int | None = None, retries: int = 1,
                  dashboard: bool = False):
    """``(cluster, client)``: the local cluster :func:`run` starts, to reuse over several batches.

    Worker processes (default: the cores this process may use), one thread each; a worker's
    death is retried ``retries`` times; ``max_memory`` bytes per worker (the nanny ends a
    worker 2% above it).  Close both when done (``client.close(); cluster.close()``).
    """
    import importlib.util
    import logging

    import dask

    distributed = _distributed()
    if workers is None:
        from ..accel import usable_cores

        workers = usable_cores()
    cfg = {"distributed.scheduler.allowed-failures": retries,
           "distributed.scheduler.worker-saturation": 1.0,
           "distributed.worker.memory.target": False, "distributed.worker.memory.spill": False,
           "distributed.worker.memory.pause": False,
           "distributed.worker.memory.terminate": 0.98 if max_memory else False}
    with dask.config.set(cfg):
        cluster = distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True,
            # the file's own limit ends a worker at max_memory; the nanny's (2% above it) is the backstop
            memory_limit=int(max_memory / 0.95) if max_memory else 0,
            # a free port on this machine only (the scheduler's HTTP server runs even without a dashboard)
            dashboard_address="127.0.0.1:0",
            scheduler_kwargs={"dashboard": bool(dashboard and importlib.util.find_spec("bokeh"))},
            silence_logs=logging.ERROR)
    return cluster, distributed.Client(cluster)


def _client(client, scheduler: str | None, workers: int | None, max_memory, retries: int, dashboard: bool):
    """(client, things to close) for the run."""
    if client is not None:
        return client, []
    distributed = _distributed()
    if scheduler is not None:
        try:
            c = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ParameterError(f"--scheduler {scheduler!r}: cannot reach the scheduler ({exc})") from None
        return c, [c]
    cluster, c = local_cluster(workers, max_memory=max_memory, retries=retries, dashboard=dashboard)
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
        progress: bool | None = None, dashboard: bool = True,
        on_start: Callable[[dict], None] | None = None) -> BatchReport:
    """Run an operation on every file of INPUTS, writing results under OUTDIR; returns a report.

    Parameters
    ----------
    inputs : str or list of str
        A glob (``**`` recursive), a folder, a manifest (.txt/.csv of paths or URLs), or
        fsspec URLs of these (:mod:`shapeflow.batch.inputs`).
    outdir : str
        Where outputs go, mirroring the input tree; it also holds the manifest
        ``shapeflow-batch.jsonl`` (:mod:`shapeflow.batch.manifest`).
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
        A progress bar (tqdm) or, without tqdm, a line every 10%; default: on a terminal.
    on_start : callable(dict), optional
        Called once the cluster runs, with ``files``, ``todo``, ``skipped``, ``workers`` and
        ``dashboard`` (its link or None).

    Returns
    -------
    BatchReport
    """
    _check(workers, timeout, max_memory, retries)
    op = parse_operation(operation, fmt=format)
    outdir = os.fspath(outdir)
    os.makedirs(outdir, exist_ok=True)
    digest = op.digest(format)
    t0 = time.perf_counter()
    with Manifest(outdir) as manifest:
        out_abs = os.path.abspath(outdir) + os.sep
        jobs = [j for j in plan_jobs(inputs, outdir, lambda ext: op.output_suffix(ext, format))
                if not os.path.abspath(j.source).startswith(out_abs)]   # earlier outputs are no inputs
        latest = {} if force else manifest.latest()
        todo, skipped = [], []
        for j in jobs:
            r = latest.get(j.source)
            if (r is not None and r.get("status") == "done" and r.get("params") == digest
                    and r.get("output") == j.output and r.get("input_stamp") == input_stamp(j.source)
                    and os.path.exists(j.output)):
                skipped.append(j.source)
            else:
                todo.append(j)
        report = BatchReport(skipped=skipped, manifest=manifest.path)
        if not todo:
            if on_start is not None:
                on_start({"files": len(jobs), "todo": 0, "skipped": len(skipped), "workers": 0, "dashboard": None})
            report.seconds = time.perf_counter() - t0
            return report
        c, owned = _client(client, scheduler, workers, max_memory, retries, dashboard)
        try:
            report.workers = sum(c.nthreads().values()) or (workers or 1)
            report.dashboard = _dashboard(c, local=len(owned) == 2)
            if on_start is not None:
                on_start({"files": len(jobs), "todo": len(todo), "skipped": len(skipped),
                          "workers": report.workers, "dashboard": report.dashboard})
            _drive(c, todo, op, format, digest, timeout, max_memory, manifest, report, progress)
        except KeyboardInterrupt:
            report.interrupted = True
        finally:
            for thing in owned:
                try:
                    thing.close()
                except Exception:   # closing a cluster that already lost its workers: nothing to keep
                    pass
            shutil.rmtree(os.path.join(manifest.state, "ended"), ignore_errors=True)
            _sweep_work_folders(todo)
    report.seconds = time.perf_counter() - t0
    return report


def _sweep_work_folders(jobs) -> None:
    """Remove the work folders a file's task leaves beside its output when its worker process ended
    mid-file (every task of this run is over, and OUTDIR's lock keeps other batches out)."""
    for folder in {os.path.dirname(os.path.abspath(j.output)) for j in jobs}:
        try:
            names = os.listdir(folder)
        except OSError:
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


def _drive(c, todo, op, fmt, digest, timeout, max_memory, manifest, report, progress) -> None:
    """Submit the files in a sliding window, record each as it finishes."""
    from distributed import as_completed

    from .. import __version__

    ended = os.path.join(manifest.state, "ended")
    os.makedirs(ended, exist_ok=True)
    window = max(32, 8 * report.workers)
    meta = {}

    def submit(job):
        key = "shapeflow-batch-" + hashlib.sha256(f"{job.source}\0{digest}".encode()).hexdigest()[:24]
        marker = os.path.join(ended, key + ".json")
        if os.path.exists(marker):
            os.remove(marker)
        fut = c.submit(run_task, job.source, job.output, op, fmt, marker, timeout, max_memory,
                       key=key, pure=False)
        meta[fut.key] = (job, marker)
        return fut

    pending = iter(todo)
    ac = as_completed([submit(j) for j in itertools.islice(pending, window)])
    bar = _Progress(len(todo), progress)
    try:
        for fut in ac:
            job, marker = meta.pop(fut.key)
            rec = _outcome(fut, job, marker)
            fut.release()
            rec.update(params=digest, input_stamp=input_stamp(job.source), shapeflow=__version__,
                       finished=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
            manifest.append(rec)
            report.records.append(rec)
            bar.update(rec)
            nxt = next(pending, None)
            if nxt is not None:
                ac.add(submit(nxt))
    finally:
        bar.close()


class _Progress:
    """A tqdm bar (extra ``progress``) or, without it, a line on stderr every 10% of the files."""

    def __init__(self, total: int, wanted: bool | None):
        self.total, self.n, self.failed = total, 0, 0
        self.bar = None
        self.lines = False
        tty = sys.stderr.isatty()
        if wanted is False or (wanted is None and not tty):
            return
        try:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="file", desc="batch", file=sys.stderr, dynamic_ncols=True)
        except ImportError:
            self.lines = True
        self.t0 = time.perf_counter()

    def update(self, rec: dict) -> None:
        self.n += 1
        self.failed += rec["status"] != "done"
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failed, refresh=False)
            self.bar.update(1)
        elif self.lines and (self.n * 10 // self.total > (self.n - 1) * 10 // self.total or self.n == self.total):
            rate = self.n / max(time.perf_counter() - self.t0, 1e-9)
            print(f"batch: {self.n}/{self.total} files ({100 * self.n // self.total}%), {self.failed} failed, "
                  f"{rate:.2f} files/s", file=sys.stderr)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
