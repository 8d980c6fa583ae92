"""What to paint on a mesh: solid colours, per-vertex or per-face values (curvature, displacement) and colour maps."""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..geometry.normals import vertex_normals
from .backend import to_rgb
from .style import CLAY

# --------------------------------------------------------------------------
# colour fields

class Field:
    """What to paint on one mesh: a solid colour, per-vertex/per-face values, or RGB colours."""

    def __init__(self, kind: str, values=None, rgb=None, label: str = "", diverging: bool = False,
                 on: str = "point", fixed=None):
        self.kind = kind            # "solid" | "scalar" | "rgb"
        self.values = values
        self.rgb = rgb
        self.label = label
        self.diverging = diverging
        self.on = on                # "point" | "cell"
        self.fixed = fixed          # natural range of the field, e.g. (0, 1) for weights


def robust_range(values: np.ndarray, diverging: bool) -> tuple[float, float]:
    """Colour range ignoring outliers: ±95th percentile of |v| (signed), else 1st–99th percentile."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return (0.0, 1.0)
    q = 99.0
    if diverging:
        lim = float(np.percentile(np.abs(v), 95.0))
        if not lim > 0:
            lim = float(np.abs(v).max()) or 1.0
        return (-lim, lim)
    lo, hi = (float(x) for x in np.percentile(v, [100 - q, q]))
    if not hi > lo:
        lo, hi = float(v.min()), float(v.max())
        if not hi > lo:
            hi = lo + 1.0
    return (lo, hi)


def color_field(mesh, color, reference, curvature_area: str = "barycentric") -> Field:
    n, m = mesh.n_vertices, mesh.n_faces
    if color is None or (isinstance(color, str) and color == "none"):
        return Field("solid", rgb=CLAY)
    if isinstance(color, str):
        if color == "curvature":
            if "curvature" in mesh.attributes:
                h = np.asarray(mesh.attributes["curvature"], dtype=np.float64)
            else:
                from ..operators import mean_curvature

                h = mean_curvature(mesh, area=curvature_area)
            bnd = mesh.topology.boundary_vertex_mask
            if bnd.any():  # no closed ring there: not a curvature, painted neutral
                h = np.where(bnd, np.nan, h)
            return Field("scalar", values=h, label="mean curvature", diverging=True)
        if color == "displacement":
            if reference is None:
                raise ParameterError("color='displacement' needs a reference mesh (reference=...)")
            if reference.n_vertices != n:
                raise ParameterError(f"displacement: the reference has {reference.n_vertices} vertices, "
                                     f"the mesh has {n}")

            d = np.einsum("ij,ij->i", mesh.vertices - reference.vertices, vertex_normals(reference))
            return Field("scalar", values=d, label="displacement along the normal", diverging=True)
        if color in ("weights", "weight"):
            w = mesh.weights
            if w is None:
                raise ParameterError("color='weights': the mesh has no 'weight' attribute")
            return Field("scalar", values=np.asarray(w, dtype=np.float64), label="weight", fixed=(0.0, 1.0))
        if color in mesh.attributes:
            a = np.asarray(mesh.attributes[color], dtype=np.float64)
            if a.ndim != 1:
                raise ParameterError(f"attribute {color!r} has {a.shape[1]} columns; one is needed to colour by it")
            return Field("scalar", values=a, label=color, diverging=bool(a.min() < 0 < a.max()))
        rgb = to_rgb(color)
        if rgb is not None:
            return Field("solid", rgb=rgb)
        have = ", ".join(mesh.attributes) or "none"
        raise ParameterError(f"unknown color {color!r}: use curvature, displacement, weights, none, "
                             f"an attribute name (this mesh has: {have}), a colour or an array")
    if isinstance(color, tuple) and len(color) in (3, 4):  # a tuple is a colour, an array is data
        rgb = to_rgb(color)
        if rgb is None:
            raise ParameterError(f"not a colour: {color!r}")
        return Field("solid", rgb=rgb)
    a = np.asarray(color)
    if a.dtype.kind not in "biuf":
        raise ParameterError(f"color array must be numeric, got dtype {a.dtype}")
    if a.ndim == 1 and a.size in (3, 4) and a.size not in (n, m):
        return Field("solid", rgb=to_rgb(a))
    if a.ndim == 1:
        if a.size not in (n, m):
            raise ParameterError(f"color array has {a.size} values; the mesh has {n} vertices and {m} faces")
        a = a.astype(np.float64)
        on = "point" if a.size == n else "cell"
        return Field("scalar", values=a, label="value", diverging=bool(np.nanmin(a) < 0 < np.nanmax(a)), on=on)
    if a.ndim == 2 and a.shape[1] in (3, 4) and a.shape[0] in (n, m):
        c = a[:, :3]
        if c.dtype != np.uint8:
            c = np.asarray(c, dtype=np.float64)
            c = np.clip(np.round(c * 255.0 if c.max() <= 1.0 else c), 0, 255).astype(np.uint8)
        return Field("rgb", rgb=np.ascontiguousarray(c), on="point" if a.shape[0] == n else "cell")
    raise ParameterError(f"color array of shape {a.shape} is neither per-vertex/per-face values nor colours")
