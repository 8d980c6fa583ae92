"""Wavefront OBJ."""

from __future__ import annotations

from typing import BinaryIO

import numpy as np

from ..errors import MeshError
from ..mesh import Mesh
from .text import Text, build_mesh, ranges, text_data, write_faces_text, write_rows

__all__ = ["read_obj", "write_obj"]


TAG_START = np.zeros(256, dtype=bool)
TAG_START[np.frombuffer(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_", np.uint8)] = True
TAG_CHAR = TAG_START.copy()
TAG_CHAR[np.frombuffer(b"0123456789.-", np.uint8)] = True
NUMBER_START = np.zeros(256, dtype=bool)
NUMBER_START[np.frombuffer(b"0123456789.-+", np.uint8)] = True


def read_obj(data: bytes, name: str) -> Mesh:
    data = text_data(data, name, "OBJ")
    txt = Text(data, name, comments=True, continuations=True)
    if txt.n_records == 0:
        raise MeshError(f"{name}: no vertices (the file has only comments or blank lines)")
    rf = txt.rec_first
    a = np.frombuffer(txt.data + b"  ", dtype=np.uint8)
    s = txt.start[rf]
    tlen = txt.end[rf] - s
    c0, c1 = a[s], a[s + 1]
    is_v = (tlen == 1) & (c0 == ord("v"))
    is_f = ((tlen == 1) & (c0 == ord("f"))) | ((tlen == 2) & (c0 == ord("f")) & (c1 == ord("o")))
    common = (tlen == 2) & (c0 == ord("v")) & ((c1 == ord("t")) | (c1 == ord("n")))
    other = np.flatnonzero(~(is_v | is_f | common))   # other tags (g, o, s, usemtl...): skipped if tag-like
    if other.size:
        _check_tags(txt, a, other, s[other], tlen[other])
    vrec = np.flatnonzero(is_v)
    vertices = _vertices(txt, vrec, name)
    frec = np.flatnonzero(is_f)
    ffirst = rf[frec]
    sizes, idx = _faces(txt, a, frec, vrec)
    vfirst = rf[vrec]
    return build_mesh(name, vertices, sizes, idx,
                      where_vertex=lambda i: f"line {txt.lineno(vfirst[i])}",
                      where_face=lambda f: f"line {txt.lineno(ffirst[f])}")


def _check_tags(txt: Text, a: np.ndarray, other: np.ndarray, so: np.ndarray, lo: np.ndarray) -> None:
    """Lines with other tags are skipped, if the tag looks like one (else: the line is an error)."""
    rf = txt.rec_first
    # a tag must be a letter or '_' followed by letters, digits, '_', '.', '-'
    chars = a[ranges(so, lo)]
    ok = TAG_CHAR[chars]
    first_ok = TAG_START[a[so]]
    tag_ok = first_ok & (np.add.reduceat(~ok, np.cumsum(lo) - lo) == 0 if chars.size else first_ok)
    # an element tag glued to its first number ('f1 2 3', 'v0.5 1 2') is a typo, not a new tag
    c1o = a[so + 1]
    k = np.where((a[so] == ord("v")) & np.isin(c1o, np.frombuffer(b"tnp", np.uint8)) & (lo > 2), 2, 1)
    glued = np.isin(a[so], np.frombuffer(b"vflp", np.uint8)) & (lo > k) & NUMBER_START[a[so + k]]
    bad = np.flatnonzero(~tag_ok | glued)
    if bad.size:
        r = int(other[bad[0]])
        tok = txt.token(rf[r])
        hint = " (a space missing after the tag?)" if glued[bad[0]] else ""
        raise txt.error(rf[r], f"unrecognised line starting with {tok}{hint}")


def _vertices(txt: Text, vrec: np.ndarray, name: str) -> np.ndarray:
    """Positions of the 'v' records: x y z [w] or x y z r g b [a]."""
    n = vrec.size
    if n == 0:
        raise MeshError(f"{name}: no vertices (no 'v' lines)")
    vfirst = txt.rec_first[vrec]
    nval = txt.rec_count[vrec] - 1
    if not (nval == 3).all():
        bad = np.flatnonzero(~np.isin(nval, (3, 4, 6, 7)))
        if bad.size:
            i = int(bad[0])
            raise txt.error(vfirst[i], f"vertex line has {int(nval[i])} values; expected x y z [w] or x y z r g b")
    vtok = (vfirst[:, None] + np.arange(1, 4)).reshape(-1)  # x y z, after the tag
    return txt.parse(vtok, np.float64, "vertex coordinate").reshape(n, 3)


def _faces(txt: Text, a: np.ndarray, frec: np.ndarray, vrec: np.ndarray):
    """Sizes and 0-based vertex indices of the 'f' records: a a/b a//c a/b/c, 1-based or negative
    (relative to the vertices so far)."""
    n = vrec.size
    ffirst = txt.rec_first[frec]
    sizes = txt.rec_count[frec] - 1
    small = np.flatnonzero(sizes < 3)
    if small.size:
        i = int(small[0])
        raise txt.error(ffirst[i], f"face has {int(sizes[i])} corners; a face needs at least 3")
    ftok = ranges(ffirst + 1, sizes)
    ends = None
    if b"/" in txt.data and ftok.size:
        slashes = np.flatnonzero(a[:-2] == ord("/"))
        ts, te = txt.start[ftok], txt.end[ftok]
        j = np.searchsorted(slashes, ts)
        first_slash = np.append(slashes, a.size)[j]
        ends = np.minimum(te, first_slash)
        empty = np.flatnonzero(ends == ts)
        if empty.size:
            t = ftok[int(empty[0])]
            raise txt.error(t, f"face corner {txt.token(t)} has no vertex index")
    raw = txt.parse(ftok, np.int64, "vertex index", ends=ends)
    zero = np.flatnonzero(raw == 0)
    if zero.size:
        raise txt.error(ftok[int(zero[0])], "vertex index 0 (OBJ indices start at 1)")
    idx = raw - 1
    neg = raw < 0
    if neg.any():
        defined = np.repeat(np.searchsorted(vrec, frec), sizes)  # 'v' lines before each face line
        idx = np.where(neg, defined + raw, idx)
        bad = np.flatnonzero(neg & (idx < 0))
        if bad.size:
            c = int(bad[0])
            raise txt.error(ftok[c], f"relative vertex index {int(raw[c])} reaches before the first vertex "
                            f"(only {int(defined[c])} defined before this line)")
    bad = np.flatnonzero(idx >= n)
    if bad.size:
        c = int(bad[0])
        raise txt.error(ftok[c], f"vertex index {int(raw[c])} out of range: the file has {n} vertices")
    return sizes, idx


def write_obj(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    f.write(f"# shapeflow: {mesh.n_vertices} vertices, {mesh.n_faces} faces\n".encode())
    write_rows(f, "v %r %r %r\n", mesh.vertices)
    write_faces_text(f, mesh, "f", 1, with_size=False)
