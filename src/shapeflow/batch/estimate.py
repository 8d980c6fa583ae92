"""A file's size in vertices from its header, and the peak memory an operation will need on it.

The figures per vertex were measured on 2026-11-24 on a generated 2M-vertex triangle
torus (binary PLY), as the process's peak resident memory above its size before
loading: load 288 B/vertex; load + one flow step 708; + one Catmull-Clark level
1,624 (per input vertex; 6× the vertices after a level of triangles, 4× of quads);
a family of 10 members 1,937 (before that day's int32 edge arrays and the lean layout
for 8M+ vertices, which lowered a flow step to 610 bytes per vertex at 2M vertices and 419
at 50M: ``bench_flow.py --scan``).  The estimate rounds the first figures up, so it errs
high; it exists so that a file far over ``--max-memory`` fails at once with its estimate
instead of taking a worker down.
"""

from __future__ import annotations

import os
import re
from typing import Sequence

__all__ = ["header_vertices", "estimate_peak_bytes"]

LOAD = 300
FLOW = 800
FAMILY_MEMBER = 130
SUBDIVIDE = 1_700      # per input vertex and level
GROWTH = 6             # vertices after one level, per vertex before (triangles; quads give 4)
#: bytes of a text file per vertex when the header does not say (OBJ, ASCII STL, glTF): a small
#: figure, so the estimate errs high
TEXT_BYTES_PER_VERTEX = 40

_PLY_VERTEX = re.compile(rb"^element[ \t]+vertex[ \t]+(\d+)", re.MULTILINE)


def header_vertices(path: str) -> int:
    """Vertices the file declares (PLY, OFF), holds (binary STL: 3 per triangle before welding),
    or, for other formats, an estimate from its size."""
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        head = f.read(65536)
    ext = os.path.splitext(path)[1].lower()
    if head.startswith(b"ply"):
        m = _PLY_VERTEX.search(head)
        if m:
            return int(m.group(1))
    if ext == ".off":
        words = re.sub(rb"#[^\n]*", b"", head).split()
        if words and words[0].endswith(b"OFF") and len(words) > 1 and words[1].isdigit():
            return int(words[1])
    if ext == ".stl" and size >= 84 and not head.lstrip().startswith(b"solid"):
        return 3 * int.from_bytes(head[80:84], "little")
    return max(1, size // TEXT_BYTES_PER_VERTEX)


def estimate_peak_bytes(n_vertices: int, options: Sequence) -> int:
    """Peak memory above the interpreter of running the steps whose options are ``options``
    (:attr:`Operation.options <shapeflow.batch.operation.Operation>`) on a mesh of ``n_vertices``."""
    from ..commands import BrushOptions, CurvatureOptions, FamilyOptions, FlowOptions, SubdivideOptions

    n = float(n_vertices)
    peak = LOAD * n
    for o in options:
        if isinstance(o, SubdivideOptions):
            for _ in range(o.levels):
                peak = max(peak, SUBDIVIDE * n)
                n *= GROWTH
        elif isinstance(o, FamilyOptions):
            peak = max(peak, (FLOW + FAMILY_MEMBER * len(o.lams)) * n)
        elif isinstance(o, (FlowOptions, BrushOptions, CurvatureOptions)):
            peak = max(peak, FLOW * n)
        else:
            peak = max(peak, LOAD * n)
    return int(peak)
