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
import re
from typing import Iterator

from ..errors import OutputError, ParameterError
from .paths import confine

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


#: the fields a later run relies on, and the JSON types each may have
_FIELDS = {"input": (str,), "output": (str, type(None)), "status": (str,), "params": (str, type(None)),
           "input_stamp": (list, type(None))}
_INPUT = re.compile(rb'^\s*\{\s*"input"\s*:\s*("(?:[^"\\]|\\.)*")')


def _json_type(value) -> str:
    for types, name in ((bool, "a boolean"), ((int, float), "a number"), (str, "a string"), (list, "an array"),
                        (dict, "an object")):
        if isinstance(value, types):
            return name
    return "null"


def _wrong_field(rec) -> str | None:
    """Why a parsed line is not a record (None when it is one)."""
    if not isinstance(rec, dict):
        return f"{_json_type(rec)}, not a record"
    for name, types in _FIELDS.items():
        if name not in rec:
            return f"no {name!r}"
        if not isinstance(rec[name], types) or isinstance(rec[name], bool):
            return f"{name!r} is {_json_type(rec[name])}"
    if rec["status"] not in ("done", "failed"):
        return f"'status' is {rec['status']!r}, not 'done' or 'failed'"
    stamp = rec["input_stamp"]
    if stamp is not None and (len(stamp) != 2 or not all(type(v) is int for v in stamp)):
        return "'input_stamp' is not [size, mtime]"
    return None


def _input_of(rec, raw: bytes) -> str | None:
    """The input a damaged line was about, when it can be told."""
    if isinstance(rec, dict) and isinstance(rec.get("input"), str):
        return rec["input"]
    m = _INPUT.match(raw)
    if m is None:
        return None
    try:
        return json.loads(m.group(1).decode("utf-8"))
    except ValueError:
        return None


class Manifest:
    """Append-only JSON Lines records of one OUTDIR, with its lock (one batch at a time)."""

    def __init__(self, outdir: str):
        self.outdir = outdir
        self.path = os.path.join(outdir, MANIFEST_NAME)
        self.state = os.path.join(outdir, STATE_DIR)
        self._file = None
        self._lock = None

    def records(self, problems: list | None = None) -> Iterator[dict]:
        """Every whole record so far.  A line cut short (anywhere, even inside a UTF-8 character),
        not JSON, or whose fields have the wrong types is skipped; ``problems`` gets
        ``(line number, reason, input or None)`` for each."""
        try:
            with open(self.path, "rb") as f:
                data = f.read()
        except FileNotFoundError:
            return
        for n, raw in enumerate(data.split(b"\n"), 1):
            if not raw.strip():
                continue
            try:
                rec = json.loads(raw.decode("utf-8"))
            except ValueError:             # UnicodeDecodeError included
                reason, rec = "cut short or not JSON", None
            else:
                reason = _wrong_field(rec)
            if reason is None:
                yield rec
            elif problems is not None:
                problems.append((n, reason, _input_of(rec, raw)))

    def latest(self, notices: list | None = None) -> dict[str, dict]:
        """The last record of every input.  An input with a damaged line has none, so its file is
        done again; ``notices`` gets one line per damaged line, saying so."""
        out, problems = {}, []
        for rec in self.records(problems):
            out[rec["input"]] = rec
        for n, reason, source in problems:
            if source is not None:
                out.pop(source, None)
            if notices is not None:
                again = f"{source} is done again" if source is not None else "its file, if any, is done again"
                notices.append(f"manifest {self.path} line {n}: {reason}; skipped ({again})")
        return out

    def open(self) -> "Manifest":
        """Take OUTDIR's lock and open the manifest for appending."""
        confine(self.outdir, self.path, "the manifest")
        os.makedirs(confine(self.outdir, self.state, "the batch's folder"), exist_ok=True)
        lock_path = confine(self.outdir, os.path.join(self.state, "lock"), "the batch's lock")
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
        try:
            self._file.write(json.dumps(record, ensure_ascii=False, default=str) + "\n")
            self._file.flush()
        except OSError as exc:      # a full disk: say which file could not be written
            raise OutputError(f"the manifest {self.path!r} cannot be written: {exc.strerror or exc}") from exc

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
