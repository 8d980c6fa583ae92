"""Feature lines: the sharp edges of a mesh drawn as lines over its surface.

``feature_lines=`` of :func:`~shapeflow.rendering.render` and
:func:`~shapeflow.rendering.render_meshes` says which edges:

* a number: the feature angle in degrees, an edge is drawn where its two faces' normals make
  more than that (:func:`shapeflow.geometry.features.angle_sharp_edges`, as ``flow(...,
  feature_angle=)`` detects them); ``True``: 30°;
* ``"mesh"``: the edges the mesh marks (OBJ smoothing-group borders and ``t crease`` tags, a
  subdivision result's creases: ``flow(..., sharp_edges="mesh")``);
* a (k, 2) array of vertex pairs, each an edge of the mesh;
* ``None`` or ``False``: none.

The lines are drawn unlit in one colour, pulled towards the camera by OpenGL's polygon
offset so that they win the depth test against the faces they lie on while surfaces in front
of them still hide them.
"""

from __future__ import annotations

import numbers
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from .. import params
from ..errors import ParameterError
from ..flow.features import mesh_sharp_edges
from ..geometry.features import angle_sharp_edges, edge_ids
from .backend import to_rgb

#: one panel's feature lines: a feature angle (degrees), True (30°), "mesh", (k, 2) vertex pairs, or None
FeatureLines = Union[None, bool, float, str, ArrayLike]

#: the feature angle ``feature_lines=True`` stands for (degrees), the flow's customary 30°
DEFAULT_ANGLE = 30.0

_HELP = "a feature angle in degrees, True (30°), 'mesh', a (k, 2) array of vertex pairs, or None"


def is_spec(x) -> bool:
    """Whether ``x`` is one panel's feature-line choice (not a list of vertex pairs)."""
    return x is None or isinstance(x, (bool, np.bool_, numbers.Real, str, np.ndarray))


def panel_specs(spec, k: int) -> list:
    """One feature-line choice per panel: a list or tuple of ``k`` choices (one per mesh), else ``spec``
    for all (a list of vertex pairs is one choice: its items are lists, not choices)."""
    if isinstance(spec, (list, tuple)) and len(spec) == k and all(is_spec(x) for x in spec):
        return list(spec)
    return [spec] * k


def feature_edges(mesh, spec, name: str = "feature_lines") -> np.ndarray:
    """(k, 2) vertex pairs of the edges ``spec`` picks on ``mesh`` (see the module docstring)."""
    if spec is None or spec is False or (isinstance(spec, np.bool_) and not spec):
        return np.zeros((0, 2), np.int64)
    t = mesh.topology
    if spec is True or isinstance(spec, np.bool_):
        mask = angle_sharp_edges(mesh, DEFAULT_ANGLE)
    elif isinstance(spec, str):
        if spec != "mesh":
            raise ParameterError(f"{name} must be {_HELP}; got {spec!r}")
        mask = mesh_sharp_edges(mesh)
    elif isinstance(spec, numbers.Real) or (isinstance(spec, np.ndarray) and spec.ndim == 0):
        mask = angle_sharp_edges(mesh, params.number(name, spec, lo=0.0, hi=180.0))
    else:
        a = np.asarray(spec) if not isinstance(spec, np.ndarray) else spec
        if a.ndim != 2 or (a.size and a.shape[1] != 2):
            raise ParameterError(f"{name} must be {_HELP}; got an array of shape {a.shape}")
        mask = np.zeros(t.n_edges, bool)
        mask[edge_ids(mesh, a.reshape(-1, 2), name)] = True
    return t.edges[mask].astype(np.int64)


def line_actor(vtk, mesh, pairs: np.ndarray, color, width: float):
    """A VTK actor drawing the edges ``pairs`` of ``mesh`` as unlit lines of ``width`` pixels."""
    poly = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    pts.SetData(vtk.np.numpy_to_vtk(np.ascontiguousarray(mesh.vertices, dtype=np.float64), deep=True))
    poly.SetPoints(pts)
    cells = vtk.vtkCellArray()
    offsets = np.arange(0, 2 * len(pairs) + 1, 2, dtype=np.int64)
    cells.SetData(vtk.np.numpy_to_vtkIdTypeArray(offsets, deep=True),
                  vtk.np.numpy_to_vtkIdTypeArray(np.ascontiguousarray(pairs, dtype=np.int64).ravel(), deep=True))
    poly.SetLines(cells)
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputData(poly)
    mapper.ScalarVisibilityOff()
    mapper.SetRelativeCoincidentTopologyLineOffsetParameters(-2.0, -8.0)   # with the window's polygon offset
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*color)
    prop.LightingOff()
    prop.SetLineWidth(float(width))
    return actor


class PanelLines:
    """The feature lines of every panel of a picture, checked before anything is drawn."""

    def __init__(self, meshes, spec, color, width):
        self.meshes = meshes
        self.pairs = [feature_edges(m, f) for m, f in zip(meshes, panel_specs(spec, len(meshes)))]
        self.rgb = to_rgb(color)
        if self.rgb is None:
            raise ParameterError(f"feature_color: not a colour: {color!r}")
        self.width = params.number("feature_width", width, lo=0.0, hi=64.0, lo_open=True)

    def actors(self, vtk, i: int) -> list:
        """The line actor of panel ``i`` (none when it has no feature line)."""
        if not len(self.pairs[i]):
            return []
        return [line_actor(vtk, self.meshes[i], self.pairs[i], self.rgb, self.width)]
