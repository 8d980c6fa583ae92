"""Vectorised text tokenising and writing shared by the text formats (OBJ, OFF, ASCII PLY)."""

from __future__ import annotations

import re
import warnings
from functools import lru_cache
from typing import BinaryIO

import numpy as np

from ..errors import MeshError
from ..mesh import Mesh

__all__ = ["WHITESPACE", "whitespace", "blank", "hashes", "blank_comments",
           "COMMENT_RE", "CONTINUATION_RE", "NUMBER_RE", "fromstring", "ranges", "Text", "strip_bom",
           "text_data", "build_mesh", "face_template", "write_rows", "write_faces_text"]


WHITESPACE = np.zeros(256, dtype=bool)
WHITESPACE[[9, 10, 11, 12, 13, 32]] = True  # the bytes bytes.split() splits on
COMMENT_RE = re.compile(rb"#[^\n]*")
CONTINUATION_RE = re.compile(rb"\\[ \t\x0b\x0c]*\n")
NUMBER_RE = {
    "f": re.compile(rb"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE),
    "i": re.compile(rb"[+-]?\d+"),
}


def whitespace(a: np.ndarray) -> np.ndarray:
    """Which bytes of ``a`` (uint8) are whitespace as ``bytes.split()`` sees it: 9-13 and 32."""
    ws = np.subtract(a, np.uint8(9)).view(bool)     # (uint8: wraps around below 9)
    np.less(ws.view(np.uint8), 5, out=ws)
    ws |= a == 32
    return ws


def blank(a: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """Set the bytes ``a[lo[i]:hi[i]]`` to spaces, in place, for increasing ranges that neither overlap
    nor touch (``hi[i] < lo[i + 1]``): by their indices when they are short, else by one running mask
    (a byte each), so the memory stays linear in ``a``."""
    lens = hi - lo
    total = int(lens.sum())
    if total == 0:
        return
    if total <= a.size // 8:
        a[ranges(lo, lens)] = 32
        return
    marks = np.zeros(a.size + 1, dtype=np.int8)
    marks[lo] = 1
    marks[hi] = -1
    inside = np.cumsum(marks[:-1], dtype=np.int8).view(bool)
    a[inside] = 32


def hashes(data: bytes) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The positions of the ``#`` bytes of ``data`` (which has one), those of the newlines from the
    first ``#`` line to the last, ending with the end of the last ``#`` line (its newline, or the
    file's end), and where that stretch of lines begins and ends: the text before and after is not
    scanned."""
    lo = data.rfind(b"\n", 0, data.find(b"#")) + 1
    hi = data.find(b"\n", data.rfind(b"#"))
    hi = len(data) if hi < 0 else hi
    a = np.frombuffer(data, dtype=np.uint8)[lo:hi]
    return np.flatnonzero(a == 35) + lo, np.append(np.flatnonzero(a == 10) + lo, hi), lo, hi


def blank_comments(data: bytes) -> tuple[bytes, int]:
    """``data`` with each ``#`` and the rest of its line turned into spaces, and where the text ends
    without a comment on the last line (the length without it)."""
    h, nl, lo, hi = hashes(data)
    e = nl[np.searchsorted(nl, h)]
    first = np.ones(h.size, dtype=bool)          # the first '#' of each line
    np.not_equal(e[1:], e[:-1], out=first[1:])
    a = np.frombuffer(data, dtype=np.uint8)[lo:hi].copy()
    blank(a, h[first] - lo, e[first] - lo)
    view = memoryview(data)
    return b"".join((view[:lo], a, view[hi:])), int(h[first][-1]) if e[-1] == len(data) else len(data)


def fromstring(buf: bytes, dtype) -> np.ndarray | None:
    """Whitespace-separated numbers -> array, or None if some text is not a number."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)  # "could not be read to its end"
        try:
            return np.fromstring(buf, dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning):
            return None


def ranges(starts: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(s, s + l)`` for each start and length."""
    lens = np.asarray(lens, dtype=np.int64)
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    before = np.cumsum(lens) - lens
    return np.repeat(np.asarray(starts, np.int64) - before, lens) + np.arange(total, dtype=np.int64)


class Text:
    """Whitespace tokens of a text file, grouped into records (non-blank lines).

    ``start``/``end`` are the byte ranges of the tokens; record ``r`` is the
    tokens ``rec_first[r] .. rec_first[r] + rec_count[r] - 1``.  Line endings
    ``\\r\\n`` and ``\\r`` count as ``\\n``; ``comments`` removes ``#`` to the end
    of a line; ``continuations`` joins lines ending in a backslash (line
    numbers in messages stay those of the file).
    """

    def __init__(self, data: bytes, name: str, *, line_offset: int = 0,
                 comments: bool = False, continuations: bool = False):
        self.name = name
        self.line_offset = line_offset
        if b"\r" in data:
            data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        self._text_end = None     # the text's end without a comment on its last line
        if comments and b"#" in data:
            data, self._text_end = blank_comments(data)  # keeps the newlines, so line numbers
        joined = None
        if continuations and b"\\" in data:
            joined = np.array([m.end() - 1 for m in CONTINUATION_RE.finditer(data)], dtype=np.int64)
            if joined.size:
                # blank the backslashes (same length), and do not break lines at ``joined``
                data = CONTINUATION_RE.sub(lambda m: b" " + m.group()[1:], data)
        self.data = data
        a = np.frombuffer(data, dtype=np.uint8)
        ws = whitespace(a)
        # a token ends where another byte is followed by whitespace (or the file's end), starts where
        # whitespace (or the file's start) is followed by another byte; one buffer for both
        mark = np.empty(a.size + 1, dtype=bool)
        mark[:1] = False
        np.less(ws[:-1], ws[1:], out=mark[1:-1])
        mark[-1] = a.size > 0 and not ws[-1]
        self.end = np.flatnonzero(mark)
        first = mark[:-1]
        first[:1] = ~ws[:1]
        np.greater(ws[:-1], ws[1:], out=first[1:])
        newline = np.equal(a, 10, out=ws)
        if joined is not None and joined.size:
            newline[joined] = False
        # token starts and line breaks in one ordered pass: a token opens a record when a line break
        # (or nothing) comes before it
        first |= newline
        events = np.flatnonzero(first)
        del first, mark
        brk = newline[events]
        del newline, ws
        self.start = events[~brk]
        opens = np.empty(events.size, dtype=bool)
        opens[:1] = True
        opens[1:] = brk[:-1]
        self.rec_first = np.flatnonzero(opens[~brk])
        self.rec_count = np.diff(np.append(self.rec_first, self.start.size))
        self._padded = None

    @property
    def n_records(self) -> int:
        return self.rec_first.size

    def lineno(self, tok) -> int:
        """Line number (1-based, in the file) of token ``tok``."""
        return self.line_offset + self.data.count(b"\n", 0, int(self.start[int(tok)])) + 1

    def last_lineno(self) -> int:
        d = self.data if self._text_end is None else self.data[:self._text_end]
        return self.line_offset + d.count(b"\n") + (0 if d.endswith(b"\n") or not d else 1)

    def token(self, tok, end=None) -> str:
        s = int(self.start[int(tok)])
        e = int(self.end[int(tok)]) if end is None else int(end)
        t = self.data[s:e].decode("latin-1")
        return repr(t if len(t) <= 40 else t[:37] + "...")

    def error(self, tok, msg: str) -> MeshError:
        return MeshError(f"{self.name}: line {self.lineno(tok)}: {msg}")

    def error_at_end(self, msg: str) -> MeshError:
        return MeshError(f"{self.name}: line {self.last_lineno()}: {msg}")

    def parse(self, toks: np.ndarray, dtype, what: str, ends: np.ndarray | None = None,
              starts: np.ndarray | None = None) -> np.ndarray:
        """Convert tokens ``toks`` (increasing indices) to numbers, in bulk.

        ``starts``/``ends`` override the tokens' first and end bytes (to read a part of each).
        """
        dtype = np.dtype(dtype)
        toks = np.asarray(toks, dtype=np.int64)
        n = toks.size
        if n == 0:
            return np.zeros(0, dtype=dtype)
        s = self.start[toks] if starts is None else starts
        e = self.end[toks] if ends is None else ends
        if ends is None and starts is None and int(toks[-1] - toks[0]) == n - 1:  # a contiguous run of tokens
            buf = self.data[int(s[0]):int(e[-1])]
        else:
            if self._padded is None:
                self._padded = np.append(np.frombuffer(self.data, dtype=np.uint8), np.uint8(32))
            lens = e - s + 1  # each token and one separator
            idx = ranges(s, lens)
            idx[np.cumsum(lens) - 1] = self._padded.size - 1
            buf = self._padded[idx].tobytes()
        out = fromstring(buf, dtype)
        if out is None or out.size != n:
            self._raise_bad_number(toks, ends, dtype, what, starts)
        return out

    def record_span(self, recs: np.ndarray) -> tuple[np.ndarray, int]:
        """A copy of the bytes from the first to the last token of records ``recs`` (increasing,
        not empty), and a space, in which only the tokens after each record's first remain: first
        tokens and the records in between are spaces; and the offset of its first byte in ``data``."""
        recs = np.asarray(recs, dtype=np.int64)
        r0, r1 = int(recs[0]), int(recs[-1])
        lo = int(self.start[self.rec_first[r0]])
        hi = int(self.end[self.rec_first[r1] + self.rec_count[r1] - 1])
        w = np.empty(hi - lo + 1, dtype=np.uint8)   # and a space: NumPy's parser reads a number to its end
        w[:-1] = np.frombuffer(self.data, dtype=np.uint8)[lo:hi]
        w[-1] = 32
        every = np.arange(r0, r1 + 1)
        member = np.zeros(every.size, dtype=bool)
        member[recs - r0] = True
        head = self.rec_first[every]
        # a member loses its first token; another record everything up to the byte before the next
        # record's first token (whitespace: the ranges stay apart)
        nxt = self.rec_first[np.minimum(every + 1, self.n_records - 1)]
        stop = np.where(member, self.end[head], self.start[nxt] - 1)
        blank(w, self.start[head] - lo, stop - lo)
        return w, lo

    def record_values(self, recs: np.ndarray, dtype) -> np.ndarray | None:
        """The numbers of the tokens after the first of each of records ``recs`` (increasing), in
        order, read in one call (:meth:`record_span`); None when one is not a number of ``dtype``
        (:meth:`parse` then names it)."""
        recs = np.asarray(recs, dtype=np.int64)
        n = int((self.rec_count[recs] - 1).sum())
        if n == 0:
            return np.zeros(0, dtype=dtype)
        out = fromstring(self.record_span(recs)[0], dtype)
        return out if out is not None and out.size == n else None

    def _raise_bad_number(self, toks, ends, dtype, what, starts=None):
        pattern = NUMBER_RE["f" if dtype.kind == "f" else "i"]
        data = self.data
        for j, t in enumerate(toks.tolist()):   # only on the way to an error: find the first bad token
            b = self.start[t] if starts is None else starts[j]
            e = self.end[t] if ends is None else ends[j]
            if not pattern.fullmatch(data, int(b), int(e)):
                raise self.error(t, f"{self.token(t, e)} is not a valid {what}")
        raise self.error(toks[0], f"cannot read the {what}s starting here")  # pragma: no cover


def strip_bom(data: bytes) -> bytes:
    """``data`` without a leading UTF-8 byte-order mark (written by some editors)."""
    return data[3:] if data.startswith(b"\xef\xbb\xbf") else data


def text_data(data: bytes, name: str, kind: str) -> bytes:
    """Checks common to text formats: not empty, not binary; strips a BOM."""
    data = strip_bom(data)
    if not data or data.isspace():     # (no stripped copy of a large file)
        raise MeshError(f"{name}: empty file")
    nul = data.find(b"\x00")
    if nul >= 0:
        line = data.count(b"\n", 0, nul) + 1
        raise MeshError(f"{name}: line {line}: binary data (NUL byte) in a text {kind} file")
    return data


def build_mesh(name: str, vertices, sizes, indices, *, attributes=None, corner_attributes=None,
               face_attributes=None, metadata=None, where_vertex=None, where_face=None) -> Mesh:
    """Make the Mesh; its validation errors are re-raised naming the file and place."""
    try:
        return Mesh.from_csr(vertices, sizes, indices, attributes=attributes, corner_attributes=corner_attributes,
                             face_attributes=face_attributes, metadata=metadata)
    except MeshError as exc:
        msg = str(exc)
        m = re.search(r"\b(face|vertex) (\d+)\b", msg)
        where = None
        if m:
            fn = where_face if m.group(1) == "face" else where_vertex
            where = fn(int(m.group(2))) if fn is not None else None
        raise MeshError(f"{name}: {where}: {msg}" if where else f"{name}: {msg}") from None


@lru_cache(maxsize=None)
def face_template(prefix: str, k: int) -> str:
    return prefix + " %d" * k + "\n"


def write_rows(f: BinaryIO, row_format: str, rows: np.ndarray, chunk: int = 65536) -> None:
    """Write a float array row by row with a %-format (``%r`` = exact repr)."""
    for i in range(0, rows.shape[0], chunk):
        block = rows[i:i + chunk]
        f.write(((row_format * block.shape[0]) % tuple(block.ravel().tolist())).encode("ascii"))


def write_faces_text(f: BinaryIO, mesh: Mesh, prefix: str, base: int, with_size: bool,
                      chunk: int = 65536) -> None:
    sizes = mesh.face_sizes
    offsets = mesh.face_offsets
    indices = mesh.face_indices
    for i in range(0, sizes.size, chunk):
        ks = sizes[i:i + chunk].tolist()
        fmt = "".join([face_template(f"{prefix}{k}" if with_size else prefix, k) for k in ks])
        corners = indices[offsets[i]:offsets[min(i + chunk, sizes.size)]]
        f.write((fmt % tuple((corners + base).tolist())).encode("ascii"))
