"""``brush IN OUT --stroke stroke.json``: sculpt a mesh along a brush stroke.

The stroke file is JSON::

    {"lambda": -50, "radius": 0.1, "points": [[x, y, z], ...]}

with optional ``"spacing"`` (dab spacing as a fraction of the radius, default
0.25; ``null`` = one dab per given point), ``"falloff"`` (``null`` or
``"smooth"``), ``"lambda_border"`` (λ_b for boundary vertices of open meshes,
default 0), ``"brush"`` (``"enhance"``, the default, for the section 4.3
brush with a signed λ, or ``"inflate"``) and, for the inflate brush,
``"strength"`` (displacement per dab as a fraction of the radius).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .common import load_mesh, note_compiling, progress, resolve_output, save_mesh, welded_for_operator
from .features import FeatureSettings, add_feature_options, drawn_edges, feature_kwargs
from .images import add_image_options
from .report import Reporter

__all__ = ["BrushOptions", "STROKE_KEYS", "MAX_STROKE_BYTES", "read_stroke", "add_parser", "run", "warm_up_brush"]

STROKE_KEYS = {"lambda", "radius", "points", "spacing", "falloff", "lambda_border", "brush", "strength"}
#: the largest stroke file read (a point is ~30 bytes of JSON: ~2 million points)
MAX_STROKE_BYTES = 64 << 20


@dataclass(frozen=True)
class BrushOptions(FeatureSettings):
    """Options of ``brush``, named as on the command line; ``stroke`` is the stroke file (read when
    the brush runs); the sharp-edge options are the flow's (the enhance brush keeps them)."""

    stroke: str = ""
    weights: str | None = None          #: a .npy/.txt file, or the name of a vertex attribute of the input
    area_normalized: bool = False
    scheme: str = "tqlbo"
    force: bool = False
    quiet: bool = False
    strict: bool = False                #: a stroke that moves no vertex is an error, not a warning
    image: str | None = None
    image_up: str = "auto"

    def __post_init__(self):
        self.check_features()


def add_parser(sub) -> None:
    """The grammar of ``brush``."""
    p = sub.add_parser(
        "brush",
        help="sculpt along a stroke with the shape-enhancement brush (or inflate)",
        description="Apply brush dabs along a stroke (section 4.3 of the paper): each dab runs one "
        "implicit flow step on the vertices inside a sphere, the rest of the mesh untouched. "
        'The stroke is a JSON file: {"lambda": L, "radius": R, "points": [[x, y, z], ...]} with '
        'optional "spacing" (fraction of the radius, default 0.25), "falloff" (null or "smooth"), '
        '"lambda_border", "brush" ("enhance" or "inflate") and "strength" (inflate).',
    )
    p.add_argument("input", metavar="IN", help="mesh file (OBJ, PLY, OFF, STL, glTF/GLB, USD) or example:NAME")
    p.add_argument("output", metavar="OUT", help="where to write the result (format from the extension)")
    p.add_argument("--stroke", required=True, metavar="JSON", help="stroke file (see above)")
    p.add_argument("--weights", metavar="FILE_OR_ATTRIBUTE",
                   help="per-vertex weights in [0,1]: a .npy/.txt file or a vertex attribute of the input")
    p.add_argument("--area-normalized", action="store_true",
                   help="area-normalised operator (eq. 9) instead of the normalised one (eq. 10)")
    p.add_argument("--scheme", choices=["tqlbo", "blender"], default="tqlbo", help="cotangent weights")
    p.add_argument("--force", action="store_true",
                   help="allow OUTPUT to be the input file, or a read-only file (overwrite it)")
    p.add_argument("--quiet", "-q", action="store_true", help="no summary on stderr")
    p.add_argument("--strict", action="store_true",
                   help="a stroke that moves no vertex is an error (exit 2, nothing written) instead of a warning")
    add_image_options(p)
    add_feature_options(p)
    p.set_defaults(options=BrushOptions)


def _number(d: dict, key: str, where: str, *, required: bool = False, default=None, positive: bool = False):
    if key not in d or d[key] is None:
        if required:
            raise ParameterError(f"{where}: missing \"{key}\"")
        return default
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ParameterError(f"{where}: \"{key}\" must be a finite number, got {json.dumps(v)}")
    if positive and v <= 0:
        raise ParameterError(f"{where}: \"{key}\" must be > 0, got {v}")
    return float(v)


def _json_int(s: str):
    # JSON integers of any length: as floats (a 5,000-digit one becomes inf and is refused as not finite)
    return float(s)


def _stroke_text(path: str) -> str:
    import os

    try:
        size = os.path.getsize(path)
        if size > MAX_STROKE_BYTES:
            raise ParameterError(f"stroke file '{path}' has {size:,} bytes; at most {MAX_STROKE_BYTES:,}")
        with open(path, "rb") as f:
            return f.read().decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ParameterError(f"stroke file '{path}' is not UTF-8 text") from None


def read_stroke(path: str) -> dict:
    """Read and check a stroke file; every problem is one ParameterError line."""
    text = _stroke_text(path)
    try:
        d = json.loads(text, parse_int=_json_int, parse_float=float)
    except json.JSONDecodeError as exc:
        raise ParameterError(f"stroke file '{path}' is not valid JSON: {exc.msg} "
                             f"(line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:   # the decoder's own guard against deep nesting (a stroke needs 2 levels)
        raise ParameterError(f"stroke file '{path}': JSON nested too deeply; a stroke needs 2 levels") from None
    where = f"stroke file '{path}'"
    if not isinstance(d, dict):
        raise ParameterError(f"{where}: expected a JSON object like "
                             '{"lambda": -50, "radius": 0.1, "points": [[0, 0, 0]]}')
    unknown = sorted(set(d) - STROKE_KEYS)
    if unknown:
        raise ParameterError(f"{where}: unknown key(s) {', '.join(map(json.dumps, unknown))}; "
                             f"expected {', '.join(sorted(STROKE_KEYS))}")
    kind = d.get("brush", "enhance")
    if kind not in ("enhance", "inflate"):
        raise ParameterError(f"{where}: \"brush\" must be \"enhance\" or \"inflate\", got {json.dumps(kind)}")
    out = {"brush": kind}
    out["radius"] = _number(d, "radius", where, required=True, positive=True)
    if kind == "enhance":
        out["lambda"] = _number(d, "lambda", where, required=True)
        out["lambda_border"] = _number(d, "lambda_border", where, default=0.0)
        if "strength" in d:
            raise ParameterError(f"{where}: \"strength\" is for the inflate brush; the enhance brush uses \"lambda\"")
    else:
        out["strength"] = _number(d, "strength", where, default=0.05)
        for k in ("lambda", "lambda_border"):
            if d.get(k) is not None:
                raise ParameterError(f"{where}: \"{k}\" is for the enhance brush; the inflate brush uses \"strength\"")
    # spacing: 0.25 when the key is absent, null = one dab per given point
    out["spacing"] = None if "spacing" in d and d["spacing"] is None else \
        _number(d, "spacing", where, positive=True, default=0.25)
    fo = d.get("falloff")
    if fo not in (None, "smooth", "none", "constant"):
        raise ParameterError(f"{where}: \"falloff\" must be null or \"smooth\", got {json.dumps(fo)}")
    out["falloff"] = fo
    out["points"] = _points(d.get("points"), where)
    return out


def _points(pts, where: str) -> list:
    if pts is None:
        raise ParameterError(f"{where}: missing \"points\" (a list of [x, y, z])")
    if not isinstance(pts, list) or not pts:
        raise ParameterError(f"{where}: \"points\" must be a non-empty list of [x, y, z]")
    for i, q in enumerate(pts):
        if (not isinstance(q, list) or len(q) != 3
                or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) for x in q)):
            raise ParameterError(f"{where}: point {i} must be [x, y, z] with three finite numbers, got {json.dumps(q)}")
    return [[float(x) for x in q] for q in pts]


def _make_brush(o: BrushOptions, operand, stroke: dict, weights, features: dict):
    from ..sculpt import Brush, InflateBrush

    if stroke["brush"] == "enhance":
        return Brush(operand, lam=stroke["lambda"], radius=stroke["radius"], falloff=stroke["falloff"],
                     lam_border=stroke["lambda_border"], weights=weights, scheme=o.scheme,
                     normalized=not o.area_normalized, undo_limit=0, feature_angle=features["feature_angle"],
                     sharp_edges=features["sharp_edges"])
    return InflateBrush(operand, strength=stroke["strength"], radius=stroke["radius"], falloff=stroke["falloff"],
                        weights=weights, undo_limit=0)


def run(o: BrushOptions, source: str, target: str, report: Reporter) -> None:
    """Sculpt ``source`` along the stroke of ``o.stroke`` and write ``target`` (and ``o.image``)."""
    from .flow import weights_arg

    stroke = read_stroke(o.stroke)
    if stroke["brush"] == "inflate" and o.uses_features:
        raise ParameterError(f"stroke file '{o.stroke}': the inflate brush moves vertices along their normals and "
                             "keeps no sharp edges; --feature-angle, --sharp-edges and --keep-marked-edges are for "
                             "the enhance brush")
    out_path = resolve_output(source, target, o.force, o.image)
    if o.image:
        from .images import check_picture_path

        check_picture_path(o.image)
    mesh = load_mesh(source, report)
    kw = {"weights": weights_arg(o.weights, mesh)}
    if stroke["brush"] == "enhance":
        kw.update(feature_kwargs(o, mesh, source, "brush", report))
    sharp = drawn_edges(mesh, kw) if o.image else None
    operand, kw, restore = welded_for_operator(mesh, kw, "brush", o.quiet, report)
    weights = kw["weights"]
    t_compile = 0.0
    if note_compiling(report, ("sculpt", "linalg", "mesh", "operators"), operand.n_vertices, min_size=0,
                      quiet=o.quiet, command="brush"):
        t_compile = warm_up_brush()     # compiled now, so the dab timings below are the dabs'
    t0 = time.perf_counter()
    brush = _make_brush(o, operand, stroke, weights, kw)
    t1 = time.perf_counter()
    centers = brush.dab_centers(stroke["points"], stroke["spacing"])
    with progress(report, len(centers), "dabs", o.quiet) as cb:
        moved = brush.stroke(centers, spacing=None, progress=cb)
    if operand is not mesh:    # welded: count the input's vertices (every copy of a moved vertex moved)
        moved = np.flatnonzero(np.isin(operand.weld_map, moved))
    t2 = time.perf_counter()
    if moved.size == 0:
        why = f"the stroke moved no vertex: {why_nothing_moved(operand, stroke, centers, weights)}"
        if o.strict:
            raise ParameterError(f"{why} (--strict)")
        report.warning(f"shapeflow brush: warning: {why}; the output is the input")
    result = restore(brush.mesh)
    save_mesh(out_path, result, o.force, report)
    if o.image:
        from .images import before_after

        before_after(o.image, mesh, result, label_after=f"{stroke['brush']} stroke", up=o.image_up, quiet=o.quiet,
                     report=report, feature_lines=sharp, command="brush")
    if not o.quiet:
        n = len(centers)
        report.message(f"shapeflow brush: {stroke['brush']}, {n} dab{'s' if n != 1 else ''} of radius "
                       f"{stroke['radius']:g}, {moved.size} of {mesh.n_vertices} vertices moved; "
                       + (f"compiling kernels {t_compile:.1f} s (first run only), " if t_compile else "")
                       + f"set-up {t1 - t0:.3f} s, "
                       f"dabs {t2 - t1:.3f} s ({1e3 * (t2 - t1) / max(n, 1):.2f} ms/dab) -> {out_path}")


def why_nothing_moved(mesh, stroke: dict, centers, weights) -> str:
    """Why a stroke left every vertex where it was, in the stroke file's terms."""
    from scipy.spatial import cKDTree

    r = stroke["radius"]
    if len(centers) == 0:
        return "it has no dab"
    dist, nearest = cKDTree(mesh.vertices).query(np.asarray(centers, dtype=np.float64))
    if dist.min() > r:
        return (f"no vertex lies within \"radius\" {r:g} of its {len(centers)} dab(s) (the nearest is "
                f"{dist.min():.4g} away; the mesh's bounding-box diagonal is {mesh.diagonal:.4g})")
    if stroke["brush"] == "enhance" and stroke["lambda"] == 0:
        return "\"lambda\" is 0"
    if stroke["brush"] == "inflate" and stroke["strength"] == 0:
        return "\"strength\" is 0"
    if weights is not None:
        return "the vertices under it have weight 0 (--weights)"
    return "the vertices under it are held (a boundary with \"lambda_border\" 0, or a flat patch)"


def warm_up_brush() -> float:
    """Compile the brush's kernels on a small sphere (one dab of each kind); returns the seconds."""
    from ..mesh import Mesh
    from ..sculpt import Brush

    t0 = time.perf_counter()
    k = 24
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, k, endpoint=False), np.linspace(0.2, np.pi - 0.2, k))
    P = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], -1).reshape(-1, 3)
    idx = np.arange(k * k).reshape(k, k)
    quads = np.stack([idx[:-1], idx[:-1, np.r_[1:k, 0]], idx[1:, np.r_[1:k, 0]], idx[1:]], -1)   # rings, wrapped
    b = Brush(Mesh(P, quads.reshape(-1, 4)), lam=-5.0, radius=0.8)
    b.dab(P[k * k // 2])
    return time.perf_counter() - t0
