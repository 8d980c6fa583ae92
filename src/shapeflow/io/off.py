"""Object File Format (OFF)."""

from __future__ import annotations

import re
import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..mesh import Mesh
from .text import Text, build_mesh, ranges, text_data, write_faces_text, write_rows

__all__ = ["read_off", "write_off"]


_OFF_RE = re.compile(rb"(ST)?(C)?(N)?(4)?(n)?OFF")


def read_off(data: bytes, name: str) -> Mesh:
    data = text_data(data, name, "OFF")
    txt = Text(data, name, comments=True)
    rf, rc = txt.rec_first, txt.rec_count
    if txt.n_records == 0:
        raise MeshError(f"{name}: empty file (only comments)")
    head = rf[0]
    m = _OFF_RE.fullmatch(txt.data, int(txt.start[head]), int(txt.end[head]))
    if not m:
        raise txt.error(head, f"not an OFF file: the header is {txt.token(head)}, expected 'OFF' (or COFF, NOFF...)")
    if m.group(4) or m.group(5):
        raise txt.error(head, "4D and nD OFF files are not supported")
    if rc[0] > 1:  # counts on the header line
        if txt.data[txt.start[head + 1]:txt.end[head + 1]] == b"BINARY":
            raise txt.error(head, "binary OFF is not supported")
        ctoks, nctok, first_data = head + 1 + np.arange(rc[0] - 1), rc[0] - 1, 1
    else:
        if txt.n_records < 2:
            raise txt.error_at_end("file ends before the vertex/face counts line")
        ctoks, nctok, first_data = rf[1] + np.arange(rc[1]), rc[1], 2
    if nctok not in (2, 3):
        raise txt.error(ctoks[0], f"expected the counts 'vertices faces [edges]', got {nctok} values")
    counts = txt.parse(ctoks, np.int64, "count")
    if (counts < 0).any():
        raise txt.error(ctoks[0], f"negative count in {counts.tolist()}")
    nv, nf = int(counts[0]), int(counts[1])
    have = txt.n_records - first_data
    if have < nv + nf:
        got_v = min(have, nv)
        what = (f"{got_v} of {nv} vertices" if got_v < nv else f"{have - nv} of {nf} faces")
        raise txt.error_at_end(f"file ends after {what} (truncated, or wrong counts in the header)")
    if have > nv + nf:
        r = first_data + nv + nf
        raise txt.error(rf[r], f"unexpected data after the last face (the header says {nv} vertices, "
                        f"{nf} faces)")
    vr = np.arange(first_data, first_data + nv)
    few = np.flatnonzero(rc[vr] < 3)
    if few.size:
        r = int(vr[few[0]])
        raise txt.error(rf[r], f"vertex line has {int(rc[r])} values, needs at least 3 (x y z)")
    vfirst = rf[vr]
    vertices = txt.parse((vfirst[:, None] + np.arange(3)).reshape(-1), np.float64,
                         "vertex coordinate").reshape(nv, 3)
    fr = np.arange(first_data + nv, first_data + nv + nf)
    ffirst = rf[fr]
    sizes = txt.parse(ffirst, np.int64, "face size")
    small = np.flatnonzero(sizes < 3)
    if small.size:
        i = int(small[0])
        raise txt.error(ffirst[i], f"face has {int(sizes[i])} corners; a face needs at least 3")
    short = np.flatnonzero(rc[fr] - 1 < sizes)
    if short.size:
        i = int(short[0])
        raise txt.error(ffirst[i], f"face line says {int(sizes[i])} corners but lists {int(rc[fr[i]] - 1)} values")
    ftok = ranges(ffirst + 1, sizes)
    idx = txt.parse(ftok, np.int64, "vertex index")
    bad = np.flatnonzero((idx < 0) | (idx >= nv))
    if bad.size:
        c = int(bad[0])
        raise txt.error(ftok[c], f"vertex index {int(idx[c])} out of range [0, {nv})")
    return build_mesh(name, vertices, sizes, idx,
                      where_vertex=lambda i: f"line {txt.lineno(vfirst[i])}",
                      where_face=lambda f: f"line {txt.lineno(ffirst[f])}")


def write_off(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    lost = ([f"vertex attribute '{k}'" for k in mesh.attributes]
            + [f"corner attribute '{k}'" for k in mesh.corner_attributes]
            + [f"face attribute '{k}'" for k in mesh.face_attributes])
    if lost:
        warnings.warn(DataLossWarning("OFF stores positions and faces only; not kept: " + ", ".join(lost)),
                      stacklevel=4)
    f.write(f"OFF\n{mesh.n_vertices} {mesh.n_faces} 0\n".encode())
    write_rows(f, "%r %r %r\n", mesh.vertices)
    write_faces_text(f, mesh, "", 0, with_size=True)
