"""VTK scene: meshes to actors, the camera framing and the offscreen window."""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from ..geometry.normals import vertex_normals
from .backend import colormap, window_class
from .fields import Field
from .style import BACKGROUND, CLAY, MARGIN, VIEW_ANGLE, VIEWS, frame

# --------------------------------------------------------------------------
# geometry -> VTK

def polydata(vtk, mesh, smooth: bool):
    if mesh.n_faces == 0:
        raise ParameterError("nothing to render: the mesh has no faces")
    poly = vtk.vtkPolyData()
    pts = vtk.vtkPoints()
    pts.SetData(vtk.np.numpy_to_vtk(np.ascontiguousarray(mesh.vertices, dtype=np.float64), deep=True))
    poly.SetPoints(pts)
    cells = vtk.vtkCellArray()
    offsets = vtk.np.numpy_to_vtkIdTypeArray(np.ascontiguousarray(mesh.face_offsets, dtype=np.int64), deep=True)
    conn = vtk.np.numpy_to_vtkIdTypeArray(np.ascontiguousarray(mesh.face_indices, dtype=np.int64), deep=True)
    cells.SetData(offsets, conn)
    poly.SetPolys(cells)
    if smooth:
        arr = vtk.np.numpy_to_vtk(np.ascontiguousarray(vertex_normals(mesh), dtype=np.float32), deep=True)
        arr.SetName("Normals")
        poly.GetPointData().SetNormals(arr)
    return poly


def lookup_table(vtk, cmap_name: str, clim):
    cmap = colormap(cmap_name)
    lut = vtk.vtkLookupTable()
    lut.SetNumberOfTableValues(256)
    table = cmap(np.linspace(0.0, 1.0, 256))
    for i in range(256):
        lut.SetTableValue(i, *table[i])
    lut.SetRange(*clim)
    lut.SetNanColor(*CLAY, 1.0)  # NaN: no value there (e.g. curvature on a boundary)
    lut.Build()
    return lut


def make_actor(vtk, mesh, field: Field, *, clim, cmap, smooth, edges, edge_color, line_width):
    poly = polydata(vtk, mesh, smooth)
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputData(poly)
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    if field.kind == "solid":
        mapper.ScalarVisibilityOff()
        prop.SetColor(*field.rgb)
    else:
        data = poly.GetPointData() if field.on == "point" else poly.GetCellData()
        if field.kind == "scalar":
            arr = vtk.np.numpy_to_vtk(np.ascontiguousarray(field.values, dtype=np.float32), deep=True)
            arr.SetName("field")
            data.SetScalars(arr)
            mapper.SetLookupTable(lookup_table(vtk, cmap, clim))
            mapper.SetScalarRange(*clim)
            mapper.UseLookupTableScalarRangeOn()
            mapper.InterpolateScalarsBeforeMappingOn()
        else:
            arr = vtk.np.numpy_to_vtk(field.rgb, deep=True)
            arr.SetName("colors")
            data.SetScalars(arr)
            mapper.SetColorModeToDirectScalars()
        mapper.ScalarVisibilityOn()
        if field.on == "point":
            mapper.SetScalarModeToUsePointData()
        else:
            mapper.SetScalarModeToUseCellData()
    prop.SetAmbient(0.12)
    prop.SetDiffuse(0.85)
    prop.SetSpecular(0.18)
    prop.SetSpecularPower(25.0)
    if smooth:
        prop.SetInterpolationToPhong()
    else:
        prop.SetInterpolationToFlat()
    if edges:
        prop.EdgeVisibilityOn()
        prop.SetEdgeColor(*edge_color)
        prop.SetLineWidth(line_width)
    return actor


# --------------------------------------------------------------------------
# camera

def view_angles(view) -> tuple[float, float]:
    if isinstance(view, str):
        v = view.strip().lower()
        if v in VIEWS:
            return VIEWS[v]
        try:
            az, el = (float(x) for x in v.split(","))
        except ValueError:
            raise ParameterError(f"unknown view {view!r}: use {', '.join(VIEWS)} or 'AZIMUTH,ELEVATION' "
                                 "in degrees from the model's front") from None
        return check_angles(az, el)
    try:
        az, el = (float(x) for x in view)
    except (TypeError, ValueError):
        raise ParameterError(f"view must be a name or (azimuth, elevation), got {view!r}") from None
    return check_angles(az, el)


def check_angles(az: float, el: float) -> tuple[float, float]:
    if not (math.isfinite(az) and math.isfinite(el)) or abs(el) > 90:
        raise ParameterError(f"view angles must be finite with |elevation| <= 90, got ({az}, {el})")
    return az, el


class Camera:
    def __init__(self, target, position, up, angle):
        self.target, self.position, self.up, self.angle = target, position, up, angle

    def apply(self, cam) -> None:
        cam.SetFocalPoint(*self.target)
        cam.SetPosition(*self.position)
        cam.SetViewUp(*self.up)
        cam.SetViewAngle(self.angle)


def camera(points: np.ndarray, view, up: str, aspect: float, margin: float = MARGIN,
            angle: float = VIEW_ANGLE, front: str | None = None) -> Camera:
    """A perspective camera looking from ``view`` (angles from the model's ``front``) that fits every
    point in the panel."""
    R, U, F = frame(up, front)
    az, el = (math.radians(a) for a in view_angles(view))
    c = math.sin(az) * math.cos(el) * R + math.sin(el) * U + math.cos(az) * math.cos(el) * F  # towards camera
    u = -math.sin(az) * math.sin(el) * R + math.cos(el) * U - math.cos(az) * math.sin(el) * F
    r = np.cross(u, c)
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (lo + hi)
    q = points - centre
    x, y, z = q @ r, q @ u, q @ c
    # centre the orthographic footprint
    cx, cy = 0.5 * (x.max() + x.min()), 0.5 * (y.max() + y.min())
    target = centre + cx * r + cy * u
    x, y = x - cx, y - cy
    ty = math.tan(math.radians(angle) / 2) * (1.0 - 2 * margin)
    tx = ty * aspect
    size = float(max(np.ptp(x), np.ptp(y), np.ptp(z)))
    if not size > 0:  # a single point: any distance will do
        return Camera(target, target + c, u, angle)
    # a point at depth z (towards the camera) projects inside iff |x| <= tx (D - z)
    dist = float(max((np.abs(x) / tx + z).max(), (np.abs(y) / ty + z).max()))
    dist = max(dist, z.max() + 1e-3 * size)
    return Camera(target, target + dist * c, u, angle)


# --------------------------------------------------------------------------
# drawing

class Window:
    """One offscreen VTK render window, reused for every panel of a picture."""

    def __init__(self, vtk, size, transparent: bool, msaa: bool = True):
        self.vtk = vtk
        cls = getattr(vtk.opengl2, window_class(), None) if window_class() else None
        self.win = cls() if cls is not None else vtk.vtkRenderWindow()
        self.win.SetOffScreenRendering(1)
        if transparent:
            self.win.SetAlphaBitPlanes(1)
        # 8x multisampling is the best anti-aliasing but costs ~1.5 s per frame with a million
        # faces in software OpenGL; big meshes get FXAA (a cheap post-process) instead
        self.msaa = msaa
        self.win.SetMultiSamples(8 if msaa else 0)
        self.win.SetSize(int(size[0]), int(size[1]))
        self.transparent = transparent
        self.size = size

    def draw(self, actors, camera: Camera) -> np.ndarray:
        """Render the actors (one, or a list drawn together) seen by ``camera``; the picture as an array.

        With more than one actor (feature lines over a surface) VTK's process-wide coincident-topology
        mode is polygon offset during this frame only, so that lines win the depth test against the
        faces they lie on (:func:`.lines.line_actor`); the caller's mode is restored afterwards.
        """
        actors = list(actors) if isinstance(actors, (list, tuple)) else [actors]
        mapper = self.vtk.vtkPolyDataMapper
        mode = mapper.GetResolveCoincidentTopology()
        if len(actors) > 1:
            mapper.SetResolveCoincidentTopologyToPolygonOffset()
        try:
            return self._draw(actors, camera)
        finally:
            mapper.SetResolveCoincidentTopology(mode)

    def _draw(self, actors: list, camera: Camera) -> np.ndarray:
        vtk = self.vtk
        ren = vtk.vtkRenderer()
        ren.SetBackground(*BACKGROUND)
        if not self.msaa:
            ren.UseFXAAOn()
        if self.transparent:
            ren.SetBackgroundAlpha(0.0)
        ren.AutomaticLightCreationOff()
        kit = vtk.vtkLightKit()
        kit.AddLightsToRenderer(ren)
        ren.TwoSidedLightingOn()
        for actor in actors:
            ren.AddActor(actor)
        camera.apply(ren.GetActiveCamera())
        ren.ResetCameraClippingRange()
        self.win.AddRenderer(ren)
        self.win.Render()
        grab = vtk.vtkWindowToImageFilter()
        grab.SetInput(self.win)
        grab.ShouldRerenderOff()  # the frame was just rendered
        grab.ReadFrontBufferOff()
        if self.transparent:
            grab.SetInputBufferTypeToRGBA()
        else:
            grab.SetInputBufferTypeToRGB()
        grab.Update()
        img = grab.GetOutput()
        w, h, _ = img.GetDimensions()
        ncomp = 4 if self.transparent else 3
        arr = vtk.np.vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, ncomp)[::-1].copy()
        self.win.RemoveRenderer(ren)
        return arr

    def close(self) -> None:
        self.win.Finalize()
