"""The local cluster of a batch, and signals held while it starts or closes.

:func:`local_cluster` runs Dask's scheduler in this process and each worker as a Dask
nanny in a process of its own, started with :mod:`subprocess` (``python -m
distributed.cli.dask_spec``), in a session of its own, its output in a log file.
``distributed.LocalCluster`` instead keeps its nannies in this process, and each makes
multiprocessing queues whose named semaphores this process's resource tracker
registers: a batch killed with SIGKILL (or ended before its cluster closed) left them
to the tracker, which printed ``resource_tracker: There appear to be 12 leaked
semaphore objects to clean up at shutdown`` (2 workers) on the terminal.  Here this
process makes no multiprocessing object at all; each nanny's queues are its own, and
a nanny always ends by closing them:

* the terminal's Ctrl-C reaches this process only (the nannies are in their own
  sessions), which closes the cluster in order;
* closing sends each nanny SIGTERM, on which it closes its worker and itself
  (SIGKILL to its process group after :data:`CLOSE_SECONDS`);
* when this process is killed, the nannies lose their scheduler and close the same way
  (within about 2 s).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import subprocess
import sys
import threading

from ..errors import OptionalDependencyError

__all__ = ["local_cluster", "deferred_signals", "distributed_module", "CLOSE_SECONDS"]

#: seconds a nanny has to close its worker and itself before its process group is killed
CLOSE_SECONDS = 20.0


def distributed_module():
    try:
        import distributed
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("distributed", "batch", "shapeflow batch", exc) from None
    return distributed


@contextlib.contextmanager
def deferred_signals():
    """SIGINT, SIGTERM and SIGHUP wait until the block has ended (in the main thread; elsewhere
    nothing changes), then arrive as they would have: a cluster is never left half started or
    half closed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    old = {}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            old[sig] = signal.signal(sig, lambda signum, frame: got.append(signum))
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        for sig in dict.fromkeys(got):
            signal.raise_signal(sig)


def _nanny_class():
    from distributed.deploy.spec import ProcessInterface

    class NannyProcess(ProcessInterface):
        """One worker of the local cluster: a Dask nanny in a process and session of its own."""

        def __init__(self, scheduler: str, name=None, nanny: dict | None = None, env: dict | None = None,
                     log: str | None = None):
            self.scheduler, self.name = scheduler, name
            self.nanny, self.env, self.log = nanny or {}, env or {}, log
            self.proc = None
            super().__init__()

        async def start(self):
            spec = json.dumps({"cls": "distributed.Nanny", "opts": {"name": self.name, **self.nanny}})
            out = open(self.log, "ab") if self.log else subprocess.DEVNULL
            try:
                self.proc = await asyncio.create_subprocess_exec(
                    sys.executable, "-m", "distributed.cli.dask_spec", self.scheduler, "--spec", spec,
                    stdin=subprocess.DEVNULL, stdout=out, stderr=out, start_new_session=True,
                    env={**os.environ, **self.env})
            finally:
                if self.log:
                    out.close()
            await super().start()

        async def close(self):
            p = self.proc
            if p is not None and p.returncode is None:
                try:
                    p.send_signal(signal.SIGTERM)
                    await asyncio.wait_for(p.wait(), CLOSE_SECONDS)
                except asyncio.TimeoutError:
                    os.killpg(p.pid, signal.SIGKILL)
                    await p.wait()
                except ProcessLookupError:
                    pass
            await super().close()

    return NannyProcess


def local_cluster(workers: int | None = None, *, max_memory: int | None = None, retries: int = 1,
                  dashboard: bool = False, log: str | None = None):
    """``(cluster, client)``: the local cluster :func:`~shapeflow.batch.run` starts, to reuse over
    several batches.

    ``workers`` worker processes (default: the cores this process may use), one thread each,
    each under a nanny in a process of its own; a worker's death is retried ``retries`` times;
    ``max_memory`` bytes per worker (the nanny ends a worker 2% above it); the nannies' output
    goes to ``log`` (a file, appended to) or nowhere.  Close both when done (``client.close();
    cluster.close()``).
    """
    import importlib.util
    import logging

    import dask

    distributed = distributed_module()
    from distributed.deploy.spec import SpecCluster

    if workers is None:
        from ..accel import usable_cores

        workers = usable_cores()
    terminate = 0.98 if max_memory else False
    env = {"DASK_DISTRIBUTED__WORKER__MEMORY__TARGET": "False", "DASK_DISTRIBUTED__WORKER__MEMORY__SPILL": "False",
           "DASK_DISTRIBUTED__WORKER__MEMORY__PAUSE": "False",
           "DASK_DISTRIBUTED__WORKER__MEMORY__TERMINATE": repr(terminate)}
    # the file's own limit ends a worker at max_memory; the nanny's (2% above it) is the backstop
    nanny = {"nthreads": 1, "host": "127.0.0.1", "dashboard": False, "death_timeout": "60s",
             "memory_limit": int(max_memory / 0.95) if max_memory else 0}
    worker = {"cls": _nanny_class(), "options": {"nanny": nanny, "env": env, "log": log}}
    # a free port on this machine only (the scheduler's HTTP server runs even without a dashboard)
    scheduler = {"cls": distributed.Scheduler,
                 "options": {"host": "127.0.0.1", "port": 0, "dashboard_address": "127.0.0.1:0",
                             "dashboard": bool(dashboard and importlib.util.find_spec("bokeh"))}}
    cfg = {"distributed.scheduler.allowed-failures": retries, "distributed.scheduler.worker-saturation": 1.0}
    with dask.config.set(cfg):
        cluster = SpecCluster(scheduler=scheduler, workers={i: worker for i in range(workers)}, worker=worker,
                              silence_logs=logging.ERROR)
    client = distributed.Client(cluster)
    try:
        client.wait_for_workers(workers, timeout=120)
    except BaseException:
        client.close()
        cluster.close()
        raise
    return cluster, client
