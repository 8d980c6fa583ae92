"""Sharp edges and creases on the command line: the options, their files, what an input file marks,
and the creases a subdivision writes back.

* :class:`FeatureSettings` — ``--feature-angle DEG``, ``--sharp-edges FILE`` and
  ``--keep-marked-edges`` of flow, enhance, smooth, family and brush; :func:`feature_kwargs` makes
  them the library's ``feature_angle`` and ``sharp_edges`` for one mesh (their union) and tells
  the user what the file marks when they are not kept.
* :func:`read_edge_file` — an edge file: a text file of ``i j`` lines (``i j value`` for
  ``--creases``; ``#`` starts a comment) or a ``.npy`` array of as many columns, 0-based vertex
  numbers, read when the options are made; :meth:`EdgeFile.pairs_on` checks them against a mesh.
  Every message names the option, the file and its line (``.npy``: its row).
* :func:`marked_edges` — the edges a file marks sharp (smoothing-group borders, ``t crease``
  tags with a positive sharpness, split normals), counted by source.
* :func:`with_crease_tags` — a subdivision's ``creases`` as ``t crease`` lines of its OBJ output.

The marked edges are not kept by default: an OBJ exported with smoothing off on every face
(``s 0``/``s off``) marks every edge, and keeping them all would freeze the mesh.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from .. import params
from ..errors import DataLossWarning, ParameterError
from .report import Reporter

__all__ = ["FeatureSettings", "EdgeFile", "Marks", "read_edge_file", "add_feature_options", "marked_edges",
           "feature_kwargs", "drawn_edges", "with_crease_tags"]

_SPACE = np.frombuffer(b" \t\r\n\x0b\x0c", np.uint8)


@dataclass(frozen=True)
class EdgeFile:
    """The rows of an edge file: vertex pairs, values (``--creases``) and where each row is."""

    option: str
    path: str
    pairs: np.ndarray = field(repr=False)               #: (k, 2) int64, 0-based vertex numbers
    values: np.ndarray | None = field(repr=False)       #: (k,) float64, or None
    lines: np.ndarray | None = field(repr=False)        #: (k,) 1-based line numbers; None for .npy (rows)

    def where(self, i: int) -> str:
        """``--sharp-edges 'e.txt': line 4`` (a .npy file: ``row 3``)."""
        place = f"row {i}" if self.lines is None else f"line {int(self.lines[i])}"
        return f"{self.option} '{self.path}': {place}"

    def pairs_on(self, mesh) -> np.ndarray:
        """The pairs, each checked to be an edge of ``mesh`` (ParameterError naming the first line that is not)."""
        n = mesh.n_vertices
        out = np.flatnonzero((self.pairs >= n).any(axis=1))
        if out.size:
            i = int(out[0])
            v = int(self.pairs[i].max())
            raise ParameterError(f"{self.where(i)}: vertex {v} is outside the mesh's {n} vertices "
                                 f"(0-based: 0 .. {n - 1})")
        e = mesh.topology.edges.astype(np.int64)
        lo, hi = self.pairs.min(axis=1), self.pairs.max(axis=1)
        missing = np.flatnonzero(~np.isin(lo * n + hi, e[:, 0] * n + e[:, 1]))
        if missing.size:
            i = int(missing[0])
            more = f" ({missing.size} such {'rows' if self.lines is None else 'lines'})" if missing.size > 1 else ""
            raise ParameterError(f"{self.where(i)}: {self.pairs[i, 0]} {self.pairs[i, 1]} is not an edge of the "
                                 f"mesh{more}")
        return self.pairs


def _data_lines(data: bytes) -> np.ndarray:
    """1-based numbers of the lines of ``data`` that hold something besides blanks and a ``#`` comment."""
    b = np.frombuffer(data, np.uint8)
    if b.size == 0:
        return np.zeros(0, np.int64)
    newline = b == 10
    line = np.cumsum(newline) - newline                      # each byte's line, its newline included
    hashes = np.flatnonzero(b == ord("#"))
    first_hash = np.full(int(line[-1]) + 1, b.size)
    np.minimum.at(first_hash, line[hashes], hashes)
    ink = ~np.isin(b, _SPACE) & (np.arange(b.size) < first_hash[line])
    return np.unique(line[ink]) + 1


def _first_bad_line(text: str, columns: int, what: str) -> str:
    """The first line of ``text`` that is not ``columns`` numbers (the error path only)."""
    for number, raw in enumerate(text.split("\n"), 1):
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        try:
            [float(w) for w in words]
            ok = len(words) == columns
        except ValueError:
            ok = False
        if not ok:
            return f"line {number}: expected {what}, got {raw.strip()[:80]!r}"
    return f"expected {what} on every line"


def _read_npy(path: str, where: str, columns: int, what: str) -> np.ndarray:
    """A (k, columns) array of numbers from a .npy file, its header checked against the file's size
    before NumPy allocates anything."""
    fmt = np.lib.format
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":
            raise ParameterError(f"{where}: not a NumPy .npy file (its first bytes are not NumPy's)")
        f.seek(0)
        try:
            version = fmt.read_magic(f)
            header = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}.get(version)
            if header is None:
                raise ValueError(f"format version {version[0]}.{version[1]}; 1.0 and 2.0 are read")
            shape, fortran, dtype = header(f)
        except (ValueError, EOFError, SyntaxError, TypeError) as exc:
            raise ParameterError(f"{where}: not a valid .npy file ({str(exc).splitlines()[0]})") from None
        if dtype.kind not in "iuf" or len(shape) != 2 or shape[1] != columns:
            raise ParameterError(f"{where}: must be a (k, {columns}) array of numbers, {what} per row; got "
                                 f"shape {shape} of {dtype}")
        left = os.fstat(f.fileno()).st_size - f.tell()
        if shape[0] * columns * dtype.itemsize > left:
            raise ParameterError(f"{where}: the header declares {shape[0]} rows, but only {left} bytes follow "
                                 "(a truncated file)")
        f.seek(0)
        return np.load(f, allow_pickle=False).astype(np.float64)


def _read_rows(path: str, option: str, columns: int, what: str) -> tuple[np.ndarray, np.ndarray | None]:
    """The numbers of an edge file as a (k, columns) float array, and each row's line (None for .npy)."""
    where = f"{option} '{path}'"
    if path.lower().endswith(".npy"):
        return _read_npy(path, where, columns, what), None
    with open(path, "rb") as f:
        data = f.read()
    data = data[3:] if data.startswith(b"\xef\xbb\xbf") else data          # a byte-order mark
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ParameterError(f"{where}: not UTF-8 text") from None
    lines = _data_lines(data)
    if lines.size == 0:
        return np.zeros((0, columns)), lines
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            a = np.loadtxt(text.split("\n"), dtype=np.float64, comments="#", ndmin=2)
    except ValueError:
        a = None
    if a is None or a.shape != (lines.size, columns):
        raise ParameterError(f"{where}: {_first_bad_line(text, columns, what)}")
    return a, lines


def read_edge_file(path: str, option: str, *, values: bool = False) -> EdgeFile:
    """Read an edge file (see the module's docstring); ``values``: a third column in [0, 1] (creases)."""
    what = "'i j value' (two vertex numbers and a crease)" if values else "'i j' (two vertex numbers)"
    if not os.path.isfile(path):
        hint = " (the input's own marked edges: --keep-marked-edges)" if path in ("mesh", "marked", "file") \
            and option == "--sharp-edges" else ""
        raise ParameterError(f"{option} '{path}': no such file{hint}")
    a, lines = _read_rows(path, option, 3 if values else 2, what)
    ef = EdgeFile(option, path, np.zeros((0, 2), np.int64), None, lines)
    if a.shape[0] == 0:
        raise ParameterError(f"{option} '{path}' lists no edge; expected {what} per line")
    p = a[:, :2]
    bad = np.flatnonzero(~(np.isfinite(p) & (p == np.round(p)) & (p >= 0) & (p < 2.0 ** 53)).all(axis=1))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"{ef.where(i)}: {p[i, 0]:g} {p[i, 1]:g} is not a pair of vertex numbers "
                             "(whole numbers from 0)")
    vals = None
    if values:
        vals = a[:, 2].copy()
        bad = np.flatnonzero(~((vals >= 0.0) & (vals <= 1.0)))
        if bad.size:
            i = int(bad[0])
            raise ParameterError(f"{ef.where(i)}: crease {vals[i]:g} is outside [0, 1] (Blender's edge crease; "
                                 "1 is infinitely sharp)")
    return EdgeFile(option, path, p.astype(np.int64), vals, lines)


# -- what a file marks ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Marks:
    """The edges a file marks sharp: ``sharp`` (E,) mask, and how many by each source."""

    sharp: np.ndarray
    groups: int             #: smoothing-group borders
    tags: int               #: edges of 't crease' tags with a positive sharpness
    normals: int = 0        #: edges where the split normals break (edges of the welded mesh)
    copies: int = 0         #: marked edges of the input that are a second copy of a welded edge

    @property
    def count(self) -> int:
        """Distinct marked edges (a seam's two copies of one edge count once)."""
        return int(self.sharp.sum()) - self.copies

    def sources(self) -> str:
        """Where the marks come from: ``smoothing-group borders``, ``'t crease' tags``, ``split normals``,
        or several with their counts (``16 smoothing-group borders, 8 in 't crease' tags``)."""
        named = [(self.groups, "smoothing-group borders"), (self.tags, "in 't crease' tags"),
                 (self.normals, "where split normals break")]
        named = [(n, what) for n, what in named if n]
        if len(named) == 1:
            return {"in 't crease' tags": "'t crease' tags", "where split normals break": "split normals"}.get(
                named[0][1], named[0][1])
        return ", ".join(f"{n} {what}" for n, what in named)


def file_crease_tags(mesh, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The ``t crease`` tags of the file ``name`` (:func:`shapeflow.geometry.features.file_creases`:
    pairs, sharpness), a malformed tag told with the file's name."""
    from ..geometry.features import file_creases

    try:
        return file_creases(mesh)
    except ParameterError as exc:
        text = str(exc)
        for prefix in ("sharp_edges='mesh': ", "the file's 't crease' tags: "):
            text = text[len(prefix):] if text.startswith(prefix) else text
        raise ParameterError(f"{name}: 't crease' tags: {text}") from None


def split_normal_marks(mesh) -> tuple[np.ndarray, int]:
    """(E,) the edges of ``mesh`` where its split normals break, found on the welded mesh (a glTF, PLY
    or USD file splits a vertex where its normals differ, so only the weld makes such an edge
    shared by two faces; each of the input's copies of a welded edge is marked), and how many
    distinct edges of the welded mesh that is."""
    from ..geometry.features import find_edges, split_normal_edges
    from ..geometry.weld import weld_if_split

    if "normal" not in mesh.corner_attributes:
        return np.zeros(mesh.topology.n_edges, bool), 0
    welded = weld_if_split(mesh)
    if welded is mesh:
        sharp = split_normal_edges(mesh)
        return sharp, int(sharp.sum())
    sharp = split_normal_edges(welded)
    e = welded.weld_map[mesh.topology.edges]
    ids, found = find_edges(welded, e)
    found &= e[:, 0] != e[:, 1]
    out = np.zeros(mesh.topology.n_edges, bool)
    out[found] = sharp[ids[found]]
    return out, int(sharp.sum())


def marked_edges(mesh, name: str) -> Marks:
    """The edges the file ``name`` marks sharp (borders of OBJ smoothing groups, creased edges, and
    where its split normals break)."""
    from ..geometry.features import edge_ids, smoothing_group_edges

    groups = smoothing_group_edges(mesh)
    pairs, s = file_crease_tags(mesh, name)
    tagged = np.zeros_like(groups)
    tagged[edge_ids(mesh, pairs[s > 0], f"{name}: 't crease' tags")] = True
    normals, distinct = split_normal_marks(mesh)
    sharp = groups | tagged | normals
    copies = int((normals & ~(groups | tagged)).sum()) - distinct if distinct else 0
    return Marks(sharp, int(groups.sum()), int(tagged.sum()), distinct, max(copies, 0))


# -- the flow's options -----------------------------------------------------------------------------

@dataclass(frozen=True)
class FeatureSettings:
    """The sharp-edge options of flow, enhance, smooth, family and brush (``feature_angle`` is
    ``--feature-angle``); the ``--sharp-edges`` file is read as the options are made
    (``sharp_file``), so a batch ships its edges with them."""

    feature_angle: float | None = None
    sharp_edges: str | None = None          #: a .txt/.npy file of vertex pairs
    keep_marked_edges: bool = False
    sharp_file: EdgeFile | None = field(default=None, init=False, repr=False, compare=False)

    def check_features(self) -> None:
        """Check ``--feature-angle`` and read ``--sharp-edges``, in the options' names."""
        if self.feature_angle is not None:
            params.number("--feature-angle", self.feature_angle, lo=0.0, hi=180.0)
        if self.sharp_edges is not None:
            object.__setattr__(self, "sharp_file", read_edge_file(self.sharp_edges, "--sharp-edges"))

    @property
    def uses_features(self) -> bool:
        return self.feature_angle is not None or self.sharp_edges is not None or self.keep_marked_edges


def add_feature_options(p) -> None:
    """``--feature-angle``, ``--sharp-edges`` and ``--keep-marked-edges``."""
    g = p.add_argument_group("sharp features (flat stays flat, straight stays straight, corners stay)")
    g.add_argument("--feature-angle", type=float, default=None, metavar="DEG",
                   help="keep the edges whose faces bend by more than DEG degrees sharp (e.g. 30)")
    g.add_argument("--sharp-edges", metavar="FILE",
                   help="keep these edges sharp: a .txt of 'i j' lines or a .npy (k, 2) of 0-based vertex numbers")
    g.add_argument("--keep-marked-edges", action="store_true",
                   help="keep the edges the input marks sharp (OBJ smoothing-group borders, 't crease' tags, "
                        "split normals); "
                        "not by default")


def feature_kwargs(o: FeatureSettings, mesh, source: str, command: str, report: Reporter) -> dict:
    """``feature_angle`` and ``sharp_edges`` (vertex pairs on ``mesh``'s numbering, or None) for the
    library; says what the file marks when ``--keep-marked-edges`` is not given."""
    pairs = []
    if o.sharp_file is not None:
        pairs.append(o.sharp_file.pairs_on(mesh))
    if o.keep_marked_edges:
        marks = marked_edges(mesh, source)
        if marks.count == 0:
            report.warning(f"shapeflow {command}: warning: --keep-marked-edges: {source} marks no sharp edge "
                           "(no smoothing-group border, no 't crease' tag, no split normal)")
        elif marks.count >= int((mesh.topology.edge_face_count >= 2).sum()):
            report.warning(f"shapeflow {command}: warning: --keep-marked-edges: {source} marks every edge sharp "
                           f"({marks.sources()}): no vertex off the boundary can move")
        pairs.append(mesh.topology.edges[marks.sharp].astype(np.int64))
    elif not getattr(o, "quiet", False):
        try:
            marks = marked_edges(mesh, source)
        except ParameterError:       # malformed tags matter only to those who keep them
            marks = None
        if marks is not None and marks.count:
            s = "s" if marks.count != 1 else ""
            report.message(f"shapeflow {command}: {source} marks {marks.count} sharp edge{s} ({marks.sources()}); "
                           "pass --keep-marked-edges to keep them")
    sharp = np.concatenate(pairs) if pairs else None
    return {"feature_angle": o.feature_angle, "sharp_edges": sharp if sharp is not None and len(sharp) else None}


def drawn_edges(mesh, kw: dict) -> np.ndarray | None:
    """The sharp edges of :func:`feature_kwargs`' ``kw`` on ``mesh`` as vertex pairs, for a picture
    (None without sharp-edge options)."""
    angle, pairs = kw.get("feature_angle"), kw.get("sharp_edges")
    if angle is None and pairs is None:
        return None
    from ..geometry.features import angle_sharp_edges

    found = mesh.topology.edges[angle_sharp_edges(mesh, angle)] if angle is not None else np.zeros((0, 2), np.int64)
    return found if pairs is None else np.concatenate([found.astype(np.int64), pairs])


# -- creases written back ---------------------------------------------------------------------------

def with_crease_tags(out, levels_changed_numbering: bool):
    """``out`` (a subdivision result) whose OBJ output carries its ``creases`` as ``t crease`` lines in
    place of the input's; the input's other ``l``/``p``/``t`` lines are kept while the numbering
    holds, and named in a DataLossWarning otherwise."""
    meta = dict(out.metadata.get("obj") or {})
    elements = list(meta.get("elements") or ())
    from ..io.obj_creases import crease_tags, is_crease_tag

    tags = crease_tags(out.creases) if getattr(out, "creases", None) is not None else []
    if not tags and not any(map(is_crease_tag, elements)):
        return out
    others = [e for e in elements if not is_crease_tag(e)]
    if others and levels_changed_numbering:
        warnings.warn(DataLossWarning(f"{len(others)} 'l'/'p'/'t' lines refer to the input's vertex numbering, "
                                      "which subdivision changed: not written"), stacklevel=2)
        others = []
    meta["elements"] = others + tags
    meta["elements_of"] = (out.n_vertices, out.face_indices)
    return out.with_metadata(obj=meta)
