"""The manifest of a batch: one JSON line per finished file in ``OUTDIR/shapeflow-batch.jsonl``.

Each record has the file's ``input``, ``output``, ``params`` (hash of the
operation and output format), ``input_stamp`` (size and modification time of a
local input), ``status`` ("done" or "failed"), ``error``, ``seconds``,
``peak_rss``, ``vertices``, ``faces``, ``report`` (the flow or family report),
``messages``, ``shapeflow`` (version) and ``finished`` (UTC).  Lines are only
appended, one per file as it finishes, so an interrupted batch keeps everything
it finished; a later run skips the files whose latest record is done with the
same parameters, the same input and an existing output.
"""

from __future__ import annotations

import json
import os
from typing import Iterator

from ..errors import ParameterError

__all__ = ["Manifest", "MANIFEST_NAME", "STATE_DIR"]

MANIFEST_NAME = "shapeflow-batch.jsonl"
#: the batch's own folder inside OUTDIR: the lock and the reasons of ended workers
STATE_DIR = ".shapeflow-batch"


def input_stamp(source: str) -> list | None:
    """``[size, mtime_ns]`` of a local input (None for a URL or a missing file)."""
    try:
        st = os.stat(source)
    except (OSError, ValueError):
        return None
    return [st.st_size, st.st_mtime_ns]


class Manifest:
    """Append-only JSON Lines records of one OUTDIR, with its lock (one batch at a time)."""

    def __init__(self, outdir: str):
        self.outdir = outdir
        self.path = os.path.join(outdir, MANIFEST_NAME)
        self.state = os.path.join(outdir, STATE_DIR)
        self._file = None
        self._lock = None

    def records(self) -> Iterator[dict]:
        """Every record so far; a line cut short by an interruption is skipped."""
        try:
            f = open(self.path, encoding="utf-8")
        except FileNotFoundError:
            return
        with f:
            for line in f:
                try:
                    rec = json.loads(line)
                except ValueError:
                    continue
                if isinstance(rec, dict) and "input" in rec:
                    yield rec

    def latest(self) -> dict[str, dict]:
        """The last record of every input."""
        out = {}
        for rec in self.records():
            out[rec["input"]] = rec
        return out

    def open(self) -> "Manifest":
        """Take OUTDIR's lock and open the manifest for appending."""
        os.makedirs(self.state, exist_ok=True)
        lock_path = os.path.join(self.state, "lock")
        self._lock = open(lock_path, "a+")
        try:
            import fcntl
        except ImportError:   # no POSIX locks (Windows): one batch per OUTDIR is the user's to keep
            fcntl = None
        if fcntl is not None:
            try:
                fcntl.flock(self._lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                self._lock.close()
                self._lock = None
                raise ParameterError(f"OUTDIR {self.outdir!r}: another shapeflow batch is writing there "
                                     "(wait for it, or choose another OUTDIR)") from None
        if os.path.exists(self.path) and os.path.getsize(self.path):
            with open(self.path, "rb") as f:      # a line cut short by a crash: start on a new line
                f.seek(-1, os.SEEK_END)
                cut = f.read(1) != b"\n"
        else:
            cut = False
        self._file = open(self.path, "a", encoding="utf-8")
        if cut:
            self._file.write("\n")
        return self

    def append(self, record: dict) -> None:
        self._file.write(json.dumps(record, ensure_ascii=False, default=str) + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()
            self._file = None
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def __enter__(self):
        return self.open()

    def __exit__(self, *exc):
        self.close()
        return False
