"""Wavefront OBJ, with everything a production asset carries.

Kept on reading and written back: positions (and ``v x y z r g b`` colours as the
vertex attribute ``"color"``), texture coordinates ``vt`` and normals ``vn`` as
the corner attributes ``"uv"`` and ``"normal"`` (tables and per-corner indices, so
their sharing and seams come back unchanged), ``usemtl``, ``g``, ``o`` and ``s``
as the face attributes ``"material"``, ``"group"``, ``"object"`` and ``"smooth"``,
and ``mtllib`` lines and comments as metadata (``# shapeflow front -z``: ``metadata["front"]``, the
axis the model faces, as PLY's ``comment shapeflow front -z``).  Polylines ``l``, points ``p`` and OpenSubdiv tags
``t`` (creases, corners, holes) refer to vertex numbers: they are kept as metadata and written
back after the faces while the vertices keep their numbering (smoothing, enhancement, the brush),
with a warning otherwise.  Curves and surfaces (and ``l``/``p``/``t`` lines with relative indices)
cannot be kept: they are counted in ``mesh.metadata["obj"]["dropped"]`` and named in a
:class:`~shapeflow.errors.DataLossWarning`.
"""

from __future__ import annotations

import os
import re
import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..mesh import Mesh
from ..mesh.attributes import Indexed, Labels
from .atomic import writing_in
from .obj_creases import crease_tags, is_crease_tag
from .ply import front_comment, front_from_comments
from .text import Text, build_mesh, fromstring, hashes, ranges, text_data, write_rows

__all__ = ["read_obj", "write_obj", "FACE_TAGS"]

TAG_START = np.zeros(256, dtype=bool)
TAG_START[np.frombuffer(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_", np.uint8)] = True
TAG_CHAR = TAG_START.copy()
TAG_CHAR[np.frombuffer(b"0123456789.-", np.uint8)] = True
NUMBER_START = np.zeros(256, dtype=bool)
NUMBER_START[np.frombuffer(b"0123456789.-+", np.uint8)] = True

#: OBJ state tags kept per face, and the face attribute each becomes
FACE_TAGS = {b"usemtl": "material", b"g": "group", b"o": "object", b"s": "smooth"}
_COMMENT = re.compile(rb"^[ \t]*#[ \t]?([^\r\n]*)", re.MULTILINE)
_OWN_HEADER = "shapeflow:"


def _tag_keys(a: np.ndarray, s: np.ndarray, tlen: np.ndarray) -> np.ndarray:
    """A number per record from its first token's length and first two bytes (see :func:`_tag`)."""
    key = np.minimum(tlen, 255).astype(np.int32) << 16
    key |= a[s].astype(np.int32)
    key |= np.where(tlen > 1, a[np.minimum(s + 1, a.size - 1)], 0).astype(np.int32) << 8
    return key


def _tag(a: np.ndarray, s: np.ndarray, tlen: np.ndarray, word: bytes, key: np.ndarray) -> np.ndarray:
    """Records whose first token is ``word`` (``key``: :func:`_tag_keys`)."""
    hit = key == (len(word) << 16 | word[0] | (word[1] << 8 if len(word) > 1 else 0))
    if len(word) > 2:
        cand = np.flatnonzero(hit)
        for j in range(2, len(word)):
            hit[cand] &= a[s[cand] + j] == word[j]
    return hit


def _texts(txt: Text, recs: np.ndarray) -> list[str]:
    """What follows the tag on each record (one string per record, '' for none)."""
    if recs.size == 0:
        return []
    rf, rc = txt.rec_first[recs], txt.rec_count[recs]
    has = rc > 1
    lo = np.where(has, txt.start[np.where(has, rf + 1, rf)], 0)
    hi = np.where(has, txt.end[rf + rc - 1], 0)
    a = np.frombuffer(txt.data, dtype=np.uint8)
    picked = a[np.minimum(ranges(lo, hi - lo + 1), a.size - 1)]
    picked[np.cumsum(hi - lo + 1) - 1] = 10                 # a newline after each
    joined = picked.tobytes().decode("utf-8", errors="replace")
    return joined.split("\n")[:-1]


def _hash_lines(data: bytes) -> bytes:
    """The lines of ``data`` that hold a '#', each ending in a newline (``_COMMENT`` finds in them
    what it finds in ``data``: it matches within a line)."""
    if b"#" not in data:
        return b""
    h, nl, _, _ = hashes(data)
    line = np.unique(np.searchsorted(nl, h))
    lo = np.where(line > 0, nl[np.maximum(line - 1, 0)] + 1, data.rfind(b"\n", 0, int(h[0])) + 1)
    lens = nl[line] + 1 - lo
    out = np.frombuffer(data, dtype=np.uint8)[np.minimum(ranges(lo, lens), len(data) - 1)]
    out[np.cumsum(lens) - 1] = 10
    return out.tobytes()


def _vertex_elements(txt: Text, a: np.ndarray, recs: np.ndarray, n_v: int, n_vt: int, n_f: int) -> tuple[list, dict]:
    """The ``l`` (polylines), ``p`` (points) and ``t`` (OpenSubdiv tags: creases, corners, holes) lines
    as ``(tag, rest of the line)``, checked as faces are (a MeshError naming the line), kept to be
    written back while the vertex numbering holds; ``l``/``p`` lines with relative (negative)
    indices would change meaning at the end of a new file: counted instead."""
    if recs.size == 0:
        return [], {}
    rf = txt.rec_first[recs]
    tags = [txt.data[int(txt.start[r]):int(txt.end[r])].decode("latin-1") for r in rf]
    is_t = np.array([t == "t" for t in tags])
    relative = np.zeros(recs.size, bool)
    relative[~is_t] = _check_polylines(txt, a, recs[~is_t], n_v, n_vt)
    rests = _texts(txt, recs)
    keep, dropped = [], {}
    for k in np.flatnonzero(is_t).tolist():      # one per tag line (few), never per vertex
        _check_tag_line(txt, int(rf[k]), rests[k].split(), n_v, n_f)
    for tag, rest, rel in zip(tags, rests, relative.tolist()):
        if rel:
            dropped[f"{tag} (relative indices)"] = dropped.get(f"{tag} (relative indices)", 0) + 1
        else:
            keep.append((tag, rest))
    return keep, dropped


def _check_polylines(txt: Text, a: np.ndarray, recs: np.ndarray, n_v: int, n_vt: int) -> np.ndarray:
    """Check the ``l v[/vt] ..`` and ``p v ..`` lines: at least 2 (``l``) or 1 (``p``) corners, whole
    indices, none 0, none beyond the file's vertices and texture coordinates; (k,) whether each line
    has a relative (negative) index."""
    rf = txt.rec_first[recs]
    cnt = txt.rec_count[recs] - 1
    is_l = txt.end[rf] - txt.start[rf] == 1
    is_l &= a[txt.start[rf]] == ord("l")
    short = np.flatnonzero(cnt < np.where(is_l, 2, 1))
    if short.size:
        i = int(short[0])
        what = "a polyline ('l') needs at least 2 vertices" if is_l[i] else "a 'p' line needs at least 1 vertex"
        raise txt.error(rf[i], f"{what}, this one has {int(cnt[i])}")
    tok = ranges(rf + 1, cnt)
    owner = np.repeat(np.arange(recs.size), cnt)
    ts, te, s1, s2 = _slashes(txt, a, tok)
    slash = s1 < te          # l: v or v/vt (a texture index after the slash); p: v only
    bad = np.flatnonzero((s1 == ts) | (s2 < te) | (slash & ((s1 + 1 == te) | ~is_l[owner])))
    if bad.size:
        c = int(bad[0])
        form = "v or v/vt" if is_l[owner[c]] else "v"
        raise txt.error(tok[c], f"{txt.token(tok[c])} is not a corner of the form {form}")
    raw = txt.parse(tok, np.int64, "vertex index", ends=s1)
    relative = np.bincount(owner, raw < 0, minlength=recs.size) > 0
    for vals, toks, n, what in ((raw, tok, n_v, "vertex"),) + _vt_part(txt, tok, s1, te, n_vt, relative, owner):
        zero = np.flatnonzero(vals == 0)
        if zero.size:
            raise txt.error(toks[int(zero[0])], f"{what} index 0 (OBJ indices start at 1)")
        over = np.flatnonzero(vals > n)
        if over.size:
            c = int(over[0])
            raise txt.error(toks[c], f"{what} index {int(vals[c])} out of range: the file has {n} {_PLURAL[what]}")
    return relative


def _vt_part(txt: Text, tok, s1, te, n_vt: int, relative: np.ndarray, owner) -> tuple:
    """The texture indices of ``l v/vt`` corners, for the checks of :func:`_check_polylines` (a relative
    one marks its line in ``relative``)."""
    has = s1 + 1 < te
    if not has.any():
        return ()
    vt = txt.parse(tok[has], np.int64, "texture coordinate index", starts=s1[has] + 1, ends=te[has])
    relative |= np.bincount(owner[has], vt < 0, minlength=relative.size) > 0
    return ((vt, tok[has], n_vt, "texture coordinate"),)


_PLURAL = {"vertex": "vertices", "texture coordinate": "texture coordinates", "face": "faces"}
#: OpenSubdiv tags whose integers number vertices (from 0) or faces (from 0)
_TAG_INDICES = {"crease": "vertex", "corner": "vertex", "hole": "face"}


def _check_tag_line(txt: Text, tok: int, words: list, n_v: int, n_f: int) -> None:
    """``t NAME i/f[/s] ints.. floats.. strings..`` (OpenSubdiv): the counts match the values, the
    integers are integers, the floats numbers, and a crease's, corner's or hole's integers number
    vertices or faces of the file (from 0, OpenSubdiv's convention)."""
    if len(words) < 2:
        raise txt.error(tok, "a 't' line needs a tag name and its counts (t NAME ints/floats[/strings] values)")
    name, counts = words[0], words[1].split("/")
    if not 2 <= len(counts) <= 3 or not all(c.isascii() and c.isdigit() for c in counts):
        raise txt.error(tok, f"'t {name}': {words[1]!r} is not the counts ints/floats[/strings]")
    ni, nf, ns = (int(c) for c in (*counts, "0")[:3])
    values = words[2:]
    if ni + nf + ns != len(values):
        raise txt.error(tok, f"'t {name} {words[1]}' declares {ni + nf + ns} values; the line has {len(values)}")
    try:
        ints = np.array(values[:ni]).astype(np.int64)
    except (ValueError, OverflowError):
        raise txt.error(tok, f"'t {name}': its {ni} integers are not all integers") from None
    try:
        np.array(values[ni:ni + nf]).astype(np.float64)
    except ValueError:
        raise txt.error(tok, f"'t {name}': its {nf} floats are not all numbers") from None
    kind = _TAG_INDICES.get(name)
    n = n_v if kind == "vertex" else n_f
    bad = np.flatnonzero((ints < 0) | (ints >= n)) if kind else np.zeros(0, np.int64)
    if bad.size:
        raise txt.error(tok, f"'t {name}': {kind} {int(ints[bad[0]])} out of range: the file has {n} {_PLURAL[kind]}, "
                        "numbered from 0 in OpenSubdiv tags")


def read_obj(data: bytes, name: str) -> Mesh:
    data = text_data(data, name, "OBJ")
    comments = [c.decode("utf-8", "replace").rstrip() for c in _COMMENT.findall(_hash_lines(data))]
    txt = Text(data, name, comments=True, continuations=True)
    if txt.n_records == 0:
        raise MeshError(f"{name}: no vertices (the file has only comments or blank lines)")
    rf = txt.rec_first
    a = np.frombuffer(txt.data, dtype=np.uint8)
    s = txt.start[rf]
    tlen = txt.end[rf] - s
    key = _tag_keys(a, s, tlen)
    is_v, is_vt, is_vn = (_tag(a, s, tlen, w, key) for w in (b"v", b"vt", b"vn"))
    is_f = _tag(a, s, tlen, b"f", key) | _tag(a, s, tlen, b"fo", key)
    is_state = {tag: _tag(a, s, tlen, tag, key) for tag in (*FACE_TAGS, b"mtllib")}
    is_elem = _tag(a, s, tlen, b"l", key) | _tag(a, s, tlen, b"p", key) | _tag(a, s, tlen, b"t", key)
    known = is_v | is_vt | is_vn | is_f | is_elem | np.logical_or.reduce(list(is_state.values()))
    other = np.flatnonzero(~known)
    dropped = _check_tags(txt, a, other, s[other], tlen[other]) if other.size else {}
    vrec = np.flatnonzero(is_v)
    vertices, attributes = _vertices(txt, vrec, name)
    frec = np.flatnonzero(is_f)
    ffirst = rf[frec]
    sizes, idx, vt_idx, vn_idx = _faces(txt, a, frec, vrec, np.flatnonzero(is_vt), np.flatnonzero(is_vn))
    corner = {}
    if is_vt.any():
        corner["uv"] = Indexed(_table(txt, np.flatnonzero(is_vt), (1, 2, 3), "texture coordinate"), vt_idx)
    if is_vn.any():
        corner["normal"] = Indexed(_table(txt, np.flatnonzero(is_vn), (3,), "normal"), vn_idx)
    face = {attr: _labels(txt, np.flatnonzero(is_state[tag]), frec)
            for tag, attr in FACE_TAGS.items() if is_state[tag].any()}
    elements, relative = _vertex_elements(txt, a, np.flatnonzero(is_elem), vrec.size, int(is_vt.sum()), frec.size)
    if relative:
        dropped = {**dropped, **relative}
    front, comments = front_from_comments([c for c in comments if not c.startswith(_OWN_HEADER)])
    meta = {"comments": comments,
            "mtllib": _texts(txt, np.flatnonzero(is_state[b"mtllib"])), "dropped": dropped}
    if meta["mtllib"]:      # where the material libraries are, for a copy written elsewhere
        meta["folder"] = os.path.dirname(os.path.abspath(name))
    if elements:
        meta["elements"] = elements
        meta["elements_of"] = (vrec.size, idx)     # the vertex numbering the lines refer to
    if dropped:
        what = ", ".join(f"{n} '{t}' line{'s' if n > 1 else ''}" for t, n in dropped.items())
        warnings.warn(DataLossWarning(f"{name}: not kept (they describe no polygon): {what}"), stacklevel=3)
    vfirst = rf[vrec]
    keep = corner or face or any(meta.values())
    metadata = {**({"obj": meta} if keep else {}), **({"front": front} if front else {})}
    return build_mesh(name, vertices, sizes, idx, attributes=attributes, corner_attributes=corner,
                      face_attributes=face, metadata=metadata or None,
                      where_vertex=lambda i: f"line {txt.lineno(vfirst[i])}",
                      where_face=lambda f: f"line {txt.lineno(ffirst[f])}")


def _check_tags(txt: Text, a: np.ndarray, other: np.ndarray, so: np.ndarray, lo: np.ndarray) -> dict:
    """Lines with other tags are counted (and not kept) if the tag looks like one, else an error."""
    rf = txt.rec_first
    # a tag must be a letter or '_' followed by letters, digits, '_', '.', '-'
    chars = a[ranges(so, lo)]
    ok = TAG_CHAR[chars]
    first_ok = TAG_START[a[so]]
    tag_ok = first_ok & (np.add.reduceat(~ok, np.cumsum(lo) - lo) == 0 if chars.size else first_ok)
    # an element tag glued to its first number ('f1 2 3', 'v0.5 1 2') is a typo, not a new tag
    c1o = _byte(a, so + 1)
    k = np.where((a[so] == ord("v")) & np.isin(c1o, np.frombuffer(b"tnp", np.uint8)) & (lo > 2), 2, 1)
    glued = np.isin(a[so], np.frombuffer(b"vflp", np.uint8)) & (lo > k) & NUMBER_START[_byte(a, so + k)]
    bad = np.flatnonzero(~tag_ok | glued)
    if bad.size:
        r = int(other[bad[0]])
        tok = txt.token(rf[r])
        hint = " (a space missing after the tag?)" if glued[bad[0]] else ""
        raise txt.error(rf[r], f"unrecognised line starting with {tok}{hint}")
    keys = a[ranges(so, lo)].tobytes().decode("ascii")
    cuts = np.cumsum(lo)
    tags = [keys[i:j] for i, j in zip(np.concatenate([[0], cuts[:-1]]).tolist(), cuts.tolist())]
    names, counts = np.unique(np.array(tags, dtype=object), return_counts=True)
    return {str(t): int(c) for t, c in zip(names, counts)}


def _byte(a: np.ndarray, i: np.ndarray) -> np.ndarray:
    """The bytes ``a[i]``, a space where ``i`` is beyond the end."""
    return np.where(i < a.size, a[np.minimum(i, a.size - 1)], 32)


def _vertices(txt: Text, vrec: np.ndarray, name: str):
    """Positions of the 'v' records (x y z [w] or x y z r g b [a]) and their colours."""
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
    vals = txt.record_values(vrec, np.float64)     # every value of every line, in one call
    off = None if vals is None else np.cumsum(nval) - nval
    if vals is None:       # some value is not a number: read x y z (and r g b) alone, naming a bad one
        vtok = (vfirst[:, None] + np.arange(1, 4)).reshape(-1)  # x y z, after the tag
        vertices = txt.parse(vtok, np.float64, "vertex coordinate").reshape(n, 3)
    elif vals.size == 3 * n:
        vertices = vals.reshape(n, 3)
    else:
        vertices = vals[off[:, None] + np.arange(3)]
    attributes = {}
    if (nval >= 6).all():
        ctok = (vfirst[:, None] + np.arange(4, 7)).reshape(-1)
        attributes["color"] = (txt.parse(ctok, np.float64, "vertex colour").reshape(n, 3) if vals is None
                               else vals[off[:, None] + np.arange(3, 6)])
    elif (nval >= 6).any():
        warnings.warn(DataLossWarning(f"{name}: only some 'v' lines have colours; colours are not kept"),
                      stacklevel=4)
    return vertices, attributes


def _table(txt: Text, recs: np.ndarray, allowed: tuple, what: str) -> np.ndarray:
    """The values of 'vt' or 'vn' records as a (t, k) table (k = the most values a record has)."""
    first = txt.rec_first[recs]
    nval = txt.rec_count[recs] - 1
    bad = np.flatnonzero(~np.isin(nval, allowed))
    if bad.size:
        i = int(bad[0])
        raise txt.error(first[i], f"{what} line has {int(nval[i])} values; expected {' or '.join(map(str, allowed))}")
    k = int(nval.max())
    out = np.zeros((recs.size, k))
    vals = txt.record_values(recs, np.float64)
    if vals is None:
        vals = txt.parse(ranges(first + 1, nval), np.float64, what)
    rows = np.repeat(np.arange(recs.size), nval)
    cols = np.arange(vals.size) - np.repeat(np.cumsum(nval) - nval, nval)
    out[rows, cols] = vals
    bad = np.flatnonzero(~np.isfinite(out).all(axis=1))
    if bad.size:
        raise txt.error(first[int(bad[0])], f"{what} is not finite")
    return out


def _labels(txt: Text, recs: np.ndarray, frec: np.ndarray) -> Labels:
    """The value of a state tag in force at each face line (the last such line before it)."""
    texts = np.array(_texts(txt, recs) + [""], dtype=object)
    which = np.searchsorted(recs, frec) - 1                # -1: no such line yet
    return Labels.from_values(texts[np.where(which >= 0, which, recs.size)])


def _slashes(txt: Text, a: np.ndarray, ftok: np.ndarray):
    """Byte positions of the first and second '/' in each corner token (its end when missing)."""
    ts, te = txt.start[ftok], txt.end[ftok]
    slashes = np.append(np.flatnonzero(a == ord("/")), a.size)
    j = np.searchsorted(slashes, ts)
    s1 = np.minimum(slashes[j], te)
    s2 = np.minimum(slashes[np.minimum(j + 1, slashes.size - 1)], te)
    s2 = np.where(s1 < te, s2, te)
    return ts, te, s1, s2


def _corner_index(txt: Text, ftok, field: tuple, count_before, n_table, what: str):
    """1-based (or negative, relative) indices of the corners that have the field -> 0-based; -1 for
    the other corners.  ``field``: which corners have one, and how to read them;
    ``count_before()``: the table's lines before each corner's face line."""
    out = np.full(ftok.size, -1, np.int64)
    has, read = field
    if not has.any():
        return out
    raw = read()
    zero = np.flatnonzero(raw == 0)
    if zero.size:
        raise txt.error(ftok[has][int(zero[0])], f"{what} 0 (OBJ indices start at 1)")
    val = raw - 1
    if (raw < 0).any():
        val = np.where(raw < 0, count_before()[has] + raw, val)
    bad = np.flatnonzero((val < 0) | (val >= n_table))
    if bad.size:
        c = int(bad[0])
        raise txt.error(ftok[has][c], f"{what} {int(raw[c])} out of range: the file has {n_table} before this line"
                        if raw[c] < 0 else f"{what} {int(raw[c])} out of range: the file has {n_table}")
    out[has] = val
    return out


def _fields_each(txt: Text, a: np.ndarray, ftok: np.ndarray) -> tuple:
    """The vertex numbers of face corners ``v``, ``v/t``, ``v//n``, ``v/t/n`` (``v/`` and ``v/t/``
    too), and for the texture and normal fields which corners have one and how to read them; each
    field read on its own, so a MeshError names the first bad one."""
    ts, te, s1, s2 = _slashes(txt, a, ftok)
    empty = np.flatnonzero(s1 == ts)
    if empty.size:
        t = ftok[int(empty[0])]
        raise txt.error(t, f"face corner {txt.token(t)} has no vertex index")
    raw = txt.parse(ftok, np.int64, "vertex index", ends=s1)

    def field(lo, hi, what):
        has = hi > lo
        return has, lambda: txt.parse(ftok[has], np.int64, what, ends=hi[has], starts=lo[has])

    return (raw, field(np.minimum(s1 + 1, te), s2, "texture coordinate index"),
            field(np.minimum(s2 + 1, te), te, "normal index"))


def _fields(txt: Text, frec: np.ndarray, ftok: np.ndarray) -> tuple | None:
    """What :func:`_fields_each` returns, from one read of all the numbers of the face lines;
    None when a corner has more than two slashes, starts with one, or a field is not a whole
    number (:func:`_fields_each` then names it)."""
    w, base = txt.record_span(frec)
    ts, te = txt.start[ftok] - base, txt.end[ftok] - base
    slash = w == 47
    if slash[ts].any():
        return None
    slash[ts] = True               # corners' first bytes and their slashes, in order
    at = np.flatnonzero(slash)
    del slash
    is_slash = w[at] == 47
    w[at[is_slash]] = 32
    k = np.flatnonzero(~is_slash)  # where each corner starts in ``at``
    n_slash = np.diff(np.append(k, at.size)) - 1
    if n_slash.size and n_slash.max() > 2:
        return None
    s1 = np.where(n_slash >= 1, at[np.minimum(k + 1, at.size - 1)], te)
    s2 = np.where(n_slash >= 2, at[np.minimum(k + 2, at.size - 1)], te)
    has_vt, has_vn = s2 > s1 + 1, te > s2 + 1    # fields that are not empty
    vals = fromstring(w, np.int64)
    if vals is None or vals.size != ftok.size + int(has_vt.sum()) + int(has_vn.sum()):
        return None
    first = np.cumsum(1 + has_vt + has_vn) - (1 + has_vt + has_vn)
    vt, vn = (first + 1)[has_vt], (first + 1 + has_vt)[has_vn]
    return vals[first], (has_vt, lambda: vals[vt]), (has_vn, lambda: vals[vn])


def _faces(txt: Text, a: np.ndarray, frec: np.ndarray, vrec: np.ndarray, vtrec: np.ndarray, vnrec: np.ndarray):
    """Sizes, 0-based vertex indices and the corners' texture-coordinate and normal indices (-1: none)
    of the 'f' records: a a/b a//c a/b/c, 1-based or negative (relative to the lines so far)."""
    n = vrec.size
    ffirst = txt.rec_first[frec]
    sizes = txt.rec_count[frec] - 1
    small = np.flatnonzero(sizes < 3)
    if small.size:
        i = int(small[0])
        raise txt.error(ffirst[i], f"face has {int(sizes[i])} corners; a face needs at least 3")
    ends = np.cumsum(sizes)

    def tok(c: int) -> int:         # the token of corner c (for messages)
        f = int(np.searchsorted(ends, c, "right"))
        return int(ffirst[f] + 1 + c - (ends[f] - sizes[f]))

    n_corners = int(ends[-1]) if ends.size else 0
    if b"/" not in txt.data or not n_corners:
        raw = txt.record_values(frec, np.int64)
        if raw is None:
            raw = txt.parse(ranges(ffirst + 1, sizes), np.int64, "vertex index")
        vt_idx = vn_idx = np.full(n_corners, -1, np.int64)
    else:
        ftok = ranges(ffirst + 1, sizes)
        fields = _fields(txt, frec, ftok)
        if fields is None:        # some corner is not a/b/c with whole numbers: read them one by one
            fields = _fields_each(txt, a, ftok)
        raw, vt, vn = fields
        before = lambda table: np.repeat(np.searchsorted(table, frec), sizes)  # noqa: E731
        vt_idx = _corner_index(txt, ftok, vt, lambda: before(vtrec), vtrec.size, "texture coordinate index")
        vn_idx = _corner_index(txt, ftok, vn, lambda: before(vnrec), vnrec.size, "normal index")
    zero = np.flatnonzero(raw == 0)
    if zero.size:
        raise txt.error(tok(int(zero[0])), "vertex index 0 (OBJ indices start at 1)")
    idx = raw - 1
    neg = raw < 0
    if neg.any():
        defined = np.repeat(np.searchsorted(vrec, frec), sizes)  # 'v' lines before each face line
        idx = np.where(neg, defined + raw, idx)
        bad = np.flatnonzero(neg & (idx < 0))
        if bad.size:
            c = int(bad[0])
            raise txt.error(tok(c), f"relative vertex index {int(raw[c])} reaches before the first vertex "
                            f"(only {int(defined[c])} defined before this line)")
    bad = np.flatnonzero(idx >= n)
    if bad.size:
        c = int(bad[0])
        raise txt.error(tok(c), f"vertex index {int(raw[c])} out of range: the file has {n} vertices")
    return sizes, idx, vt_idx, vn_idx


# --------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------

def _state_lines(mesh: Mesh) -> dict[int, str]:
    """The state lines (o, g, s, usemtl) to write before each face where one of them changes."""
    out: dict[int, list] = {}
    for tag in ("o", "g", "s", "usemtl"):
        lab = mesh.face_attributes.get(FACE_TAGS[tag.encode()])
        if not isinstance(lab, Labels) or mesh.n_faces == 0:
            continue
        c = lab.codes
        change = np.flatnonzero(np.concatenate([[c[0] >= 0], c[1:] != c[:-1]]))
        names = lab.values()
        for q in change.tolist():     # one line per change of state (runs of faces, not faces)
            out.setdefault(q, []).append(f"{tag} {names[q]}".rstrip() + "\n")
    return {q: "".join(v).replace("%", "%%") for q, v in out.items()}


def _obj_losses(mesh: Mesh) -> list[str]:
    lost = [f"vertex attribute '{k}'" for k, v in mesh.attributes.items()
            if not (k == "color" and v.ndim == 2 and v.shape[1] == 3)]
    lost += [f"corner attribute '{k}'" for k in mesh.corner_attributes if k not in ("uv", "normal")]
    lost += [f"face attribute '{k}'" for k, v in mesh.face_attributes.items()
             if k not in FACE_TAGS.values() or not isinstance(v, Labels)]
    return lost


def write_obj(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    lost = _obj_losses(mesh)
    if lost:
        warnings.warn(DataLossWarning("OBJ cannot store: " + ", ".join(lost) + " (PLY keeps vertex and face "
                                      "attributes)"), stacklevel=4)
    meta = mesh.metadata.get("obj", {})
    head = [f"# {_OWN_HEADER} {mesh.n_vertices} vertices, {mesh.n_faces} faces"]
    head += [f"# {c}" for c in front_comment(mesh) + meta.get("comments", [])]
    head += [f"mtllib {m}" for m in meta.get("mtllib", [])]
    _warn_missing_libraries(meta)
    f.write(("\n".join(head) + "\n").encode("utf-8"))
    color = mesh.attributes.get("color")
    if color is not None and color.ndim == 2 and color.shape[1] == 3:
        write_rows(f, "v %r %r %r %r %r %r\n", np.hstack([mesh.vertices, np.asarray(color, np.float64)]))
    else:
        write_rows(f, "v %r %r %r\n", mesh.vertices)
    uv, nrm = mesh.corner_attributes.get("uv"), mesh.corner_attributes.get("normal")
    uv, nrm = (_as_indexed(x) for x in (uv, nrm))
    if uv is not None:
        k = uv.values.shape[1]
        write_rows(f, "vt" + " %r" * k + "\n", np.asarray(uv.values, np.float64))
    if nrm is not None:
        write_rows(f, "vn %r %r %r\n", np.asarray(nrm.values, np.float64))
    _write_faces(f, mesh, uv, nrm, _state_lines(mesh))
    elements = meta.get("elements")
    creases = getattr(mesh, "creases", None)
    if creases is not None:     # a subdivision's creases replace the file's crease tags
        elements = [e for e in elements or () if not is_crease_tag(e)]
    if elements:
        n, idx = meta["elements_of"]
        if n == mesh.n_vertices and np.array_equal(idx, mesh.face_indices):
            f.write("".join(f"{tag} {rest}\n" for tag, rest in elements).encode("utf-8"))
        else:
            warnings.warn(DataLossWarning(f"{len(elements)} 'l'/'p'/'t' lines refer to the input's vertex numbering, "
                                          "which changed (subdivision?): not written"), stacklevel=4)
    if creases is not None:
        f.write("".join(f"{tag} {rest}\n" for tag, rest in crease_tags(creases)).encode("utf-8"))


def _warn_missing_libraries(meta: dict) -> None:
    """A DataLossWarning naming the material libraries ('mtllib') the written file names but its
    folder does not hold, while the source's folder does (or the source is unknown): they are not
    copied (nor the textures they name); the warning says where they are."""
    folder, src = writing_in(), meta.get("folder")
    names = [w for line in meta.get("mtllib", []) for w in line.split()]
    # missing beside the output, and there beside the source (a library the source lacks too loses nothing)
    missing = [n for n in names if folder is not None and not os.path.isfile(os.path.join(folder, n))
               and (src is None or os.path.isfile(os.path.join(src, n)))]
    if not missing:
        return
    warnings.warn(DataLossWarning(
        f"the material librar{'y' if len(missing) == 1 else 'ies'} {', '.join(map(repr, missing))} named by "
        f"'mtllib' {'is' if len(missing) == 1 else 'are'} not in the output's folder: materials will not show "
        + (f"until {'it is' if len(missing) == 1 else 'they are'} copied there from {src} (with the textures "
           "named in it)" if src is not None else "(shapeflow writes the OBJ file only)")), stacklevel=5)


def _as_indexed(attr):
    if attr is None or isinstance(attr, Indexed):
        return attr
    a = np.asarray(attr, np.float64)
    return Indexed(a.reshape(a.shape[0], -1), np.arange(a.shape[0]))


def _write_faces(f: BinaryIO, mesh: Mesh, uv, nrm, states: dict, chunk: int = 65536) -> None:
    """Face lines: each corner as v, v/t, v//n or v/t/n, with the state lines in front of their face."""
    sizes, offsets, indices = mesh.face_sizes, mesh.face_offsets, mesh.face_indices
    c = indices.size
    ti = uv.index if uv is not None else np.full(c, -1)
    ni = nrm.index if nrm is not None else np.full(c, -1)
    # a face writes texture / normal indices only when every corner has one
    face_of = mesh.topology.corner_face
    has_t = np.logical_and.reduceat(ti >= 0, offsets[:-1]) if c else np.zeros(0, bool)
    has_n = np.logical_and.reduceat(ni >= 0, offsets[:-1]) if c else np.zeros(0, bool)
    cols = np.stack([indices + 1, ti + 1, ni + 1], axis=1)
    use = np.stack([np.ones(c, bool), has_t[face_of], has_n[face_of]], axis=1)
    pattern = {(False, False): " %d", (True, False): " %d/%d", (False, True): " %d//%d", (True, True): " %d/%d/%d"}
    for i in range(0, sizes.size, chunk):
        j = min(i + chunk, sizes.size)
        fmt = "".join([states.get(q, "") + "f" + pattern[(t, nn)] * k + "\n"
                       for q, k, t, nn in zip(range(i, j), sizes[i:j].tolist(), has_t[i:j].tolist(),
                                              has_n[i:j].tolist())])
        lo, hi = int(offsets[i]), int(offsets[j])
        vals = cols[lo:hi][use[lo:hi]]
        f.write((fmt % tuple(vals.tolist())).encode("utf-8"))
