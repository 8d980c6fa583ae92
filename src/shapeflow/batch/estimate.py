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


def estimate_peak_bytes(n_vertices: int, steps: tuple[tuple[str, ...], ...]) -> int:
    """Peak memory above the interpreter of running ``steps`` on a mesh of ``n_vertices``."""
    n = float(n_vertices)
    peak = LOAD * n
    for cmd, *opts in steps:
        if cmd == "subdivide":
            levels = _int_option(opts, ("--levels", "-l"), 1)
            for _ in range(max(levels, 0)):
                peak = max(peak, SUBDIVIDE * n)
                n *= GROWTH
        elif cmd == "family":
            peak = max(peak, (FLOW + FAMILY_MEMBER * _members(opts)) * n)
        elif cmd in ("flow", "enhance", "smooth", "brush", "curvature"):
            peak = max(peak, FLOW * n)
        else:
            peak = max(peak, LOAD * n)
    return int(peak)


def _int_option(opts, names, default: int) -> int:
    for i, o in enumerate(opts):
        for name in names:
            if o == name and i + 1 < len(opts):
                return _as_int(opts[i + 1], default)
            if o.startswith(name + "=") or (len(name) == 2 and o.startswith(name) and len(o) > 2):
                return _as_int(o[len(name):].lstrip("="), default)
    return default


def _as_int(text: str, default: int) -> int:
    try:
        return int(text)
    except ValueError:
        return default


def _members(opts) -> int:
    """Members of a family from --lambdas or --from/--to/--step (a bound: 100 when unknown)."""
    for i, o in enumerate(opts):
        if o == "--lambdas" and i + 1 < len(opts):
            return len(opts[i + 1].split(","))
    vals = {}
    for name in ("--from", "--to", "--step"):
        if name in opts and opts.index(name) + 1 < len(opts):
            try:
                vals[name] = float(opts[opts.index(name) + 1])
            except ValueError:
                pass
    if "--to" in vals and vals.get("--step"):
        return max(1, int(abs((vals["--to"] - vals.get("--from", 0.0)) / vals["--step"])) + 1)
    return 100
