"""A batch's progress on stderr: a tqdm bar on a terminal, a line every few seconds elsewhere.

Off a terminal (a log file, a pipe, a job scheduler's output) every ``interval``
seconds one line::

    shapeflow batch: 12/40 files, 11 done, 1 failed, 2.35 files/s, ETA 0:00:12

(files finished of those to do, of them done and failed, files per second since the
first was submitted, and the time left at that rate, ``H:MM:SS``, or ``unknown``
before the first file has finished).  The workers' own progress bars never show: each
file runs with a stderr that is no terminal (:mod:`shapeflow.batch.task`).
"""

from __future__ import annotations

import math
import sys
import threading
import time

__all__ = ["Progress", "progress_line"]


def _clock(seconds: float) -> str:
    s = int(math.ceil(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


def progress_line(finished: int, total: int, done: int, failed: int, seconds: float) -> str:
    """The progress line of a batch ``seconds`` after its first file was submitted."""
    rate = finished / seconds if seconds > 0 else 0.0
    eta = _clock((total - finished) / rate) if rate > 0 else "unknown"
    return (f"shapeflow batch: {finished}/{total} files, {done} done, {failed} failed, {rate:.2f} files/s, "
            f"ETA {eta}")


class Progress:
    """The progress of ``total`` files: ``wanted`` False shows nothing; otherwise a tqdm bar when
    stderr is a terminal and tqdm is installed, else a :func:`progress_line` every ``interval`` s."""

    def __init__(self, total: int, wanted: bool | None, interval: float = 10.0):
        self.total, self.done, self.failed = total, 0, 0
        self.bar = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self.t0 = time.perf_counter()
        if wanted is False:
            return
        if sys.stderr.isatty():
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, unit="file", desc="batch", file=sys.stderr, dynamic_ncols=True)
                return
            except ImportError:
                pass
        self.interval = interval
        self._thread = threading.Thread(target=self._tick, name="shapeflow-batch-progress", daemon=True)
        self._thread.start()

    def _tick(self) -> None:
        while not self._stop.wait(self.interval):
            with self._lock:
                line = progress_line(self.done + self.failed, self.total, self.done, self.failed,
                                     time.perf_counter() - self.t0)
            print(line, file=sys.stderr, flush=True)

    def update(self, rec: dict) -> None:
        with self._lock:
            if rec["status"] == "done":
                self.done += 1
            else:
                self.failed += 1
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failed, refresh=False)
            self.bar.update(1)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self.bar is not None:
            self.bar.close()
