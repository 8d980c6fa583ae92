"""Headless pictures of meshes: shaded, coloured by a field, with wireframe.

Rendering uses VTK (the optional extra ``shapeflow[render]``: ``vtk>=9.4``,
plus Pillow for text and PNG files and matplotlib for the colour maps, which
the VTK wheel installs anyway).  It needs no display and no GPU: since 9.4 the
PyPI VTK wheel picks an offscreen OpenGL back end at run time.  On Linux this
module asks for EGL first (Mesa's software rasteriser ``llvmpipe`` is enough;
Debian/Ubuntu packages ``libegl1 libegl-mesa0 libgl1-mesa-dri``), then OSMesa
(``libosmesa6``), then an X display if ``DISPLAY`` is set.  Without any of them
VTK would crash the interpreter, so this module checks first and raises
:class:`RenderBackendError` instead.  A user's own
``VTK_DEFAULT_OPENGL_WINDOW`` is respected.

What is drawn
-------------
* Hidden surfaces are removed by OpenGL's z-buffer.
* ``shading="smooth"``: area-weighted vertex normals (computed here, as
  :func:`shapeflow.geometry.vertex_normals`), Phong interpolation;
  ``"flat"``: one normal per triangle of the rasterised polygon.
* ``edges=True`` draws every polygon's own edges (quads as quads, n-gons as
  n-gons); VTK hides the diagonals of the triangles it rasterises.
* Colour fields (``color=``): ``"curvature"`` (signed mean curvature with
  barycentric areas, or the mesh's ``curvature`` attribute when it has one:
  blue concave, red convex, symmetric range), ``"displacement"`` (signed
  displacement along the reference's vertex normals, red outward), ``"weights"``
  (the ``weight`` attribute, 0..1), any other attribute name, an array of
  per-vertex or per-face values, an (n, 3|4) array of colours, a single colour
  (``"#4477aa"``, ``(0.2, 0.4, 0.8)``, a matplotlib colour name), or ``"none"``
  (plain clay).  Field ranges are robust, so a few sliver triangles do not
  wash the picture out: ±(95th percentile of |value|) for signed fields, the
  1st to 99th percentile otherwise (0..1 for weights); ``clim=`` overrides.
* Framing: a perspective camera (20° vertical view angle) placed so that the
  projection of every vertex fits the panel with a small margin.  Views are
  azimuth/elevation about the ``up`` axis (``"y"``, the OBJ convention, or
  ``"z"``): ``front`` = (0, 0) looks at the model from +z (y-up) or from −y
  (z-up), ``side`` = (90, 0) from +x, ``top`` = (0, 90), ``iso`` = (35, 25).
  :func:`render_meshes` frames all meshes with one camera by default, so
  sizes and positions are comparable between panels (``framing="rows"``: one
  camera per grid row; ``"each"``: one per mesh), and colours every panel's
  field with one range and one colour bar; ``color``, ``reference``,
  ``edges`` and ``shading`` may be given per mesh.
* Meshes of more than 300k faces are anti-aliased with FXAA instead of 8×
  multisampling, which costs ~1.5 s a frame at a million faces in software
  OpenGL (``benchmarks/bench_render.py``: a million faces in 1–1.6 s,
  3–4 s when the curvature has to be computed too).

Both functions return the picture as a ``uint8`` array ``(h, w, 3)`` (or
``(h, w, 4)`` with ``transparent=True``) and write it as a PNG when given a
path.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence

import numpy as np

from .errors import OptionalDependencyError, ParameterError
from .geometry import vertex_normals

__all__ = ["render", "render_meshes", "family_colors", "available", "require", "save_png",
           "RenderBackendError", "VIEWS"]

#: named views: (azimuth, elevation) in degrees about the up axis
VIEWS = {"front": (0.0, 0.0), "side": (90.0, 0.0), "back": (180.0, 0.0), "top": (0.0, 90.0),
         "bottom": (0.0, -90.0), "iso": (35.0, 25.0)}

#: (right, up, front) axes of the model for each ``up`` choice
_FRAMES = {
    "y": (np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])),
    "z": (np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, -1.0, 0])),
}

VIEW_ANGLE = 20.0   # vertical field of view of the camera, degrees
MARGIN = 0.04       # free border around the framed model, fraction of the panel
CLAY = (0.80, 0.78, 0.74)
EDGE_COLOR = (0.12, 0.12, 0.14)
BACKGROUND = (1.0, 1.0, 1.0)
MSAA_MAX_FACES = 300_000  # larger meshes: FXAA instead of 8x multisampling (speed)


class RenderBackendError(OptionalDependencyError):
    """VTK is installed but no offscreen OpenGL (EGL, OSMesa or X) is usable."""

    def __init__(self, message: str):
        ImportError.__init__(self, message)
        self.extra = "render"


# --------------------------------------------------------------------------
# optional dependencies and the OpenGL back end

_BACKEND_CHECKED = False
_WINDOW_CLASS: str | None = None   # the offscreen window class chosen by _choose_backend (None: VTK's default)


def _egl_works() -> bool:
    """True if libEGL can initialise a display without X (device or surfaceless platform)."""
    import ctypes

    try:
        lib = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return False
    try:
        gpa = lib.eglGetProcAddress
        gpa.restype = ctypes.c_void_p
        gpa.argtypes = [ctypes.c_char_p]
        lib.eglInitialize.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]
        lib.eglInitialize.restype = ctypes.c_uint
        lib.eglTerminate.argtypes = [ctypes.c_void_p]
        p_get = gpa(b"eglGetPlatformDisplayEXT")
        if not p_get:
            return False
        get_display = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p)(p_get)
        candidates = []
        p_query = gpa(b"eglQueryDevicesEXT")
        if p_query:
            query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                                     ctypes.POINTER(ctypes.c_int))(p_query)
            devs = (ctypes.c_void_p * 16)()
            n = ctypes.c_int(0)
            if query(16, devs, ctypes.byref(n)):
                candidates += [(0x313F, devs[i]) for i in range(n.value)]  # EGL_PLATFORM_DEVICE_EXT
        candidates.append((0x31DD, None))  # EGL_PLATFORM_SURFACELESS_MESA
        for platform, native in candidates:
            dpy = get_display(platform, native, None)
            if not dpy:
                continue
            major, minor = ctypes.c_int(0), ctypes.c_int(0)
            if lib.eglInitialize(dpy, ctypes.byref(major), ctypes.byref(minor)):
                lib.eglTerminate(dpy)
                return True
    except Exception:  # pragma: no cover - exotic libEGL builds
        return False
    return False


def _osmesa_present() -> bool:
    import ctypes
    import ctypes.util

    for name in ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so", ctypes.util.find_library("OSMesa")):
        if not name:
            continue
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            pass
    return False


def _choose_backend() -> None:
    """Choose the offscreen OpenGL window class (Linux), once; the environment is not touched.

    EGL where it initialises, else OSMesa, else VTK's default window (X, with
    ``DISPLAY``).  A ``VTK_DEFAULT_OPENGL_WINDOW`` the user set is left to VTK.
    """
    global _BACKEND_CHECKED, _WINDOW_CLASS
    if _BACKEND_CHECKED:
        return
    if sys.platform.startswith("linux") and not os.environ.get("VTK_DEFAULT_OPENGL_WINDOW"):
        if _egl_works():
            _WINDOW_CLASS = "vtkEGLRenderWindow"
        elif _osmesa_present():
            _WINDOW_CLASS = "vtkOSOpenGLRenderWindow"
        elif not os.environ.get("DISPLAY"):
            raise RenderBackendError(
                "rendering needs offscreen OpenGL and none is usable here: install Mesa's EGL "
                "(Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) or OSMesa "
                "(libosmesa6), or set DISPLAY")
    _BACKEND_CHECKED = True


def _vtk():
    """The VTK classes used here, imported on first use."""
    try:
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (registers the OpenGL factories)
        from vtkmodules.util import numpy_support
        from vtkmodules.vtkCommonCore import vtkLookupTable, vtkObject, vtkPoints
        from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
        from vtkmodules.vtkRenderingCore import (
            vtkActor,
            vtkLightKit,
            vtkPolyDataMapper,
            vtkRenderer,
            vtkRenderWindow,
            vtkWindowToImageFilter,
        )
    except ImportError as exc:
        raise OptionalDependencyError("vtk", "render", "rendering") from exc
    import vtkmodules.vtkRenderingOpenGL2 as opengl2
    from types import SimpleNamespace

    return SimpleNamespace(np=numpy_support, opengl2=opengl2, vtkObject=vtkObject, vtkPoints=vtkPoints,
                           vtkLookupTable=vtkLookupTable,
                           vtkCellArray=vtkCellArray, vtkPolyData=vtkPolyData, vtkActor=vtkActor,
                           vtkLightKit=vtkLightKit, vtkPolyDataMapper=vtkPolyDataMapper,
                           vtkRenderer=vtkRenderer, vtkRenderWindow=vtkRenderWindow,
                           vtkWindowToImageFilter=vtkWindowToImageFilter)


def _pil():
    try:
        from PIL import Image, ImageDraw, ImageFont
    except ImportError as exc:
        raise OptionalDependencyError("pillow", "render", "rendering") from exc
    return Image, ImageDraw, ImageFont


def _colormap(name: str):
    try:
        import matplotlib
    except ImportError as exc:
        raise OptionalDependencyError("matplotlib", "render", "colour maps") from exc
    try:
        return matplotlib.colormaps[name]
    except KeyError:
        raise ParameterError(f"unknown colour map {name!r} (any matplotlib colour map name)") from None


def _to_rgb(spec) -> tuple[float, float, float] | None:
    """A single colour (name, '#rrggbb', RGB tuple 0..1 or 0..255), or None if spec is not one."""
    if isinstance(spec, str):
        try:
            from matplotlib.colors import to_rgb
        except ImportError:
            return None
        try:
            return tuple(float(c) for c in to_rgb(spec))
        except ValueError:
            return None
    a = np.asarray(spec, dtype=np.float64) if not isinstance(spec, np.ndarray) else spec.astype(np.float64)
    if a.shape in ((3,), (4,)) and np.all(np.isfinite(a)):
        if a.max() > 1.0:
            a = a / 255.0
        return tuple(float(c) for c in np.clip(a[:3], 0, 1))
    return None


def require() -> None:
    """Raise :class:`~shapeflow.errors.OptionalDependencyError` unless rendering can work here."""
    _choose_backend()
    _vtk()
    _pil()
    _colormap("viridis")


def available() -> bool:
    """True if rendering works here (VTK importable and an offscreen OpenGL back end)."""
    try:
        require()
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------
# colour fields

class _Field:
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


def _robust_range(values: np.ndarray, diverging: bool) -> tuple[float, float]:
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


def _field(mesh, color, reference, curvature_area: str = "barycentric") -> _Field:
    n, m = mesh.n_vertices, mesh.n_faces
    if color is None or (isinstance(color, str) and color == "none"):
        return _Field("solid", rgb=CLAY)
    if isinstance(color, str):
        if color == "curvature":
            if "curvature" in mesh.attributes:
                h = np.asarray(mesh.attributes["curvature"], dtype=np.float64)
            else:
                from .operators import mean_curvature

                h = mean_curvature(mesh, area=curvature_area)
            bnd = mesh.topology.boundary_vertex_mask
            if bnd.any():  # no closed ring there: not a curvature, painted neutral
                h = np.where(bnd, np.nan, h)
            return _Field("scalar", values=h, label="mean curvature", diverging=True)
        if color == "displacement":
            if reference is None:
                raise ParameterError("color='displacement' needs a reference mesh (reference=...)")
            if reference.n_vertices != n:
                raise ParameterError(f"displacement: the reference has {reference.n_vertices} vertices, "
                                     f"the mesh has {n}")

            d = np.einsum("ij,ij->i", mesh.vertices - reference.vertices, vertex_normals(reference))
            return _Field("scalar", values=d, label="displacement along the normal", diverging=True)
        if color in ("weights", "weight"):
            w = mesh.weights
            if w is None:
                raise ParameterError("color='weights': the mesh has no 'weight' attribute")
            return _Field("scalar", values=np.asarray(w, dtype=np.float64), label="weight", fixed=(0.0, 1.0))
        if color in mesh.attributes:
            a = np.asarray(mesh.attributes[color], dtype=np.float64)
            if a.ndim != 1:
                raise ParameterError(f"attribute {color!r} has {a.shape[1]} columns; one is needed to colour by it")
            return _Field("scalar", values=a, label=color, diverging=bool(a.min() < 0 < a.max()))
        rgb = _to_rgb(color)
        if rgb is not None:
            return _Field("solid", rgb=rgb)
        have = ", ".join(mesh.attributes) or "none"
        raise ParameterError(f"unknown color {color!r}: use curvature, displacement, weights, none, "
                             f"an attribute name (this mesh has: {have}), a colour or an array")
    if isinstance(color, tuple) and len(color) in (3, 4):  # a tuple is a colour, an array is data
        rgb = _to_rgb(color)
        if rgb is None:
            raise ParameterError(f"not a colour: {color!r}")
        return _Field("solid", rgb=rgb)
    a = np.asarray(color)
    if a.dtype.kind not in "biuf":
        raise ParameterError(f"color array must be numeric, got dtype {a.dtype}")
    if a.ndim == 1 and a.size in (3, 4) and a.size not in (n, m):
        return _Field("solid", rgb=_to_rgb(a))
    if a.ndim == 1:
        if a.size not in (n, m):
            raise ParameterError(f"color array has {a.size} values; the mesh has {n} vertices and {m} faces")
        a = a.astype(np.float64)
        on = "point" if a.size == n else "cell"
        return _Field("scalar", values=a, label="value", diverging=bool(np.nanmin(a) < 0 < np.nanmax(a)), on=on)
    if a.ndim == 2 and a.shape[1] in (3, 4) and a.shape[0] in (n, m):
        c = a[:, :3]
        if c.dtype != np.uint8:
            c = np.asarray(c, dtype=np.float64)
            c = np.clip(np.round(c * 255.0 if c.max() <= 1.0 else c), 0, 255).astype(np.uint8)
        return _Field("rgb", rgb=np.ascontiguousarray(c), on="point" if a.shape[0] == n else "cell")
    raise ParameterError(f"color array of shape {a.shape} is neither per-vertex/per-face values nor colours")


# --------------------------------------------------------------------------
# geometry -> VTK

def _polydata(vtk, mesh, smooth: bool):
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


def _lookup_table(vtk, cmap_name: str, clim):
    cmap = _colormap(cmap_name)
    lut = vtk.vtkLookupTable()
    lut.SetNumberOfTableValues(256)
    table = cmap(np.linspace(0.0, 1.0, 256))
    for i in range(256):
        lut.SetTableValue(i, *table[i])
    lut.SetRange(*clim)
    lut.SetNanColor(*CLAY, 1.0)  # NaN: no value there (e.g. curvature on a boundary)
    lut.Build()
    return lut


def _actor(vtk, mesh, field: _Field, *, clim, cmap, smooth, edges, edge_color, line_width):
    poly = _polydata(vtk, mesh, smooth)
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
            mapper.SetLookupTable(_lookup_table(vtk, cmap, clim))
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

def _view_angles(view) -> tuple[float, float]:
    if isinstance(view, str):
        v = view.strip().lower()
        if v in VIEWS:
            return VIEWS[v]
        try:
            az, el = (float(x) for x in v.split(","))
        except ValueError:
            raise ParameterError(f"unknown view {view!r}: use {', '.join(VIEWS)} or 'AZIMUTH,ELEVATION' "
                                 "in degrees") from None
        return _check_angles(az, el)
    try:
        az, el = (float(x) for x in view)
    except (TypeError, ValueError):
        raise ParameterError(f"view must be a name or (azimuth, elevation), got {view!r}") from None
    return _check_angles(az, el)


def _check_angles(az: float, el: float) -> tuple[float, float]:
    if not (math.isfinite(az) and math.isfinite(el)) or abs(el) > 90:
        raise ParameterError(f"view angles must be finite with |elevation| <= 90, got ({az}, {el})")
    return az, el


class _Camera:
    def __init__(self, target, position, up, angle):
        self.target, self.position, self.up, self.angle = target, position, up, angle

    def apply(self, cam) -> None:
        cam.SetFocalPoint(*self.target)
        cam.SetPosition(*self.position)
        cam.SetViewUp(*self.up)
        cam.SetViewAngle(self.angle)


def _camera(points: np.ndarray, view, up: str, aspect: float, margin: float = MARGIN,
            angle: float = VIEW_ANGLE) -> _Camera:
    """A perspective camera looking from ``view`` that fits every point in the panel."""
    if up not in _FRAMES:
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    az, el = (math.radians(a) for a in _view_angles(view))
    R, U, F = _FRAMES[up]
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
        return _Camera(target, target + c, u, angle)
    # a point at depth z (towards the camera) projects inside iff |x| <= tx (D - z)
    dist = float(max((np.abs(x) / tx + z).max(), (np.abs(y) / ty + z).max()))
    dist = max(dist, z.max() + 1e-3 * size)
    return _Camera(target, target + dist * c, u, angle)


# --------------------------------------------------------------------------
# drawing

class _Window:
    """One offscreen VTK render window, reused for every panel of a picture."""

    def __init__(self, vtk, size, transparent: bool, msaa: bool = True):
        self.vtk = vtk
        cls = getattr(vtk.opengl2, _WINDOW_CLASS, None) if _WINDOW_CLASS else None
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

    def draw(self, actor, camera: _Camera) -> np.ndarray:
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


_FONT_PATH: list = []


def _font(size: int):
    """DejaVu Sans from matplotlib's data (it has Greek: λ), else Pillow's default font."""
    _, _, ImageFont = _pil()
    if not _FONT_PATH:
        path = None
        try:
            import matplotlib

            cand = os.path.join(matplotlib.get_data_path(), "fonts", "ttf", "DejaVuSans.ttf")
            path = cand if os.path.exists(cand) else None
        except ImportError:
            pass
        _FONT_PATH.append(path)
    if _FONT_PATH[0]:
        try:
            return ImageFont.truetype(_FONT_PATH[0], size)
        except OSError:
            pass
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: fixed bitmap font
        return ImageFont.load_default()


def _fmt(x: float) -> str:
    if x == 0:
        return "0"
    return f"{x:.3g}".replace("e-0", "e-").replace("e+0", "e")


def _colorbar_font_size(width: int) -> int:
    return int(np.clip(round(0.016 * width), 11, 16))


def _colorbar_height(width: int) -> int:
    """Height of the colour-bar band: title line, bar, tick labels."""
    fs = _colorbar_font_size(width)
    return int(round(fs * 1.5 + max(8, 0.9 * fs) + fs * 1.6 + 6))


def _colorbar(width: int, height: int, cmap_name: str, clim, label: str, diverging: bool,
              transparent: bool) -> np.ndarray:
    """A horizontal colour bar: the title above it, tick values under it."""
    Image, ImageDraw, _ = _pil()
    mode = "RGBA" if transparent else "RGB"
    bg = (255, 255, 255, 0) if transparent else (255, 255, 255)
    im = Image.new(mode, (width, height), bg)
    draw = ImageDraw.Draw(im)
    fs = _colorbar_font_size(width)
    font = _font(fs)
    ink = (40, 40, 40, 255) if transparent else (40, 40, 40)
    bar_w = int(min(0.5 * width, 40 * fs))
    bar_h = int(max(8, 0.9 * fs))
    x0 = (width - bar_w) // 2
    y0 = int(round(fs * 1.5))
    if label:
        tw = draw.textlength(label, font=font)
        draw.text(((width - tw) / 2, y0 - fs * 1.35), label, fill=ink, font=font)
    grad = _colormap(cmap_name)(np.linspace(0, 1, bar_w))[:, :3]
    grad = (np.round(grad * 255)).astype(np.uint8)
    strip = np.repeat(grad[None], bar_h, axis=0)
    if transparent:
        strip = np.concatenate([strip, np.full(strip.shape[:2] + (1,), 255, np.uint8)], axis=2)
    im.paste(Image.fromarray(strip, mode), (x0, y0))
    draw.rectangle([x0 - 1, y0 - 1, x0 + bar_w, y0 + bar_h], outline=ink)
    ticks = [clim[0], clim[1]]
    if diverging and clim[0] < 0 < clim[1]:
        ticks.insert(1, 0.0)
    for t in ticks:
        fx = (t - clim[0]) / (clim[1] - clim[0])
        xp = x0 + int(round(fx * (bar_w - 1)))
        draw.line([xp, y0 + bar_h, xp, y0 + bar_h + 3], fill=ink)
        txt = _fmt(t)
        tw = draw.textlength(txt, font=font)
        draw.text((min(max(xp - tw / 2, 0), width - tw), y0 + bar_h + 4), txt, fill=ink, font=font)
    return np.asarray(im)


def _label_band(width: int, height: int, text: str, transparent: bool) -> np.ndarray:
    Image, ImageDraw, _ = _pil()
    mode = "RGBA" if transparent else "RGB"
    im = Image.new(mode, (width, height), (255, 255, 255, 0) if transparent else (255, 255, 255))
    draw = ImageDraw.Draw(im)
    fs = max(10, int(height * 0.66))
    font = _font(fs)
    while fs > 8 and draw.textlength(text, font=font) > width - 4:
        fs -= 1
        font = _font(fs)
    tw = draw.textlength(text, font=font)
    draw.text(((width - tw) / 2, (height - fs) / 2 - 1), text, fill=(30, 30, 30, 255) if transparent else (30, 30, 30),
              font=font)
    return np.asarray(im)


def save_png(path, image: np.ndarray, *, force: bool = False) -> None:
    """Write an (h, w, 3|4) uint8 array as a PNG, atomically (:func:`shapeflow.io.atomic_write`)."""
    from .io import atomic_write

    Image, _, _ = _pil()
    atomic_write(os.fspath(path), lambda f: Image.fromarray(image).save(f, format="PNG"), force=force)


def _check_size(size) -> tuple[int, int]:
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError):
        raise ParameterError(f"size must be (width, height), got {size!r}") from None
    if not (16 <= w <= 16384 and 16 <= h <= 16384):
        raise ParameterError(f"size must be between 16 and 16384 pixels each way, got {w}x{h}")
    return w, h


def family_colors(n: int, cmap: str = "coolwarm") -> list[tuple[float, float, float]]:
    """``n`` colours from blue to red, for a family of shapes (figure 1 of the paper)."""
    if n < 1:
        return []
    c = _colormap(cmap)(np.linspace(0.0, 1.0, n) if n > 1 else [0.0])
    return [tuple(float(x) for x in row[:3]) for row in c]


# --------------------------------------------------------------------------
# public API

def render(mesh, path=None, *, color="curvature", reference=None, view="front", up: str = "y",
           edges: bool = False, size=(800, 600), shading: str = "smooth", colorbar: bool = True,
           cmap: str | None = None, clim=None, label: str | None = None, transparent: bool = False,
           curvature_area: str = "barycentric", edge_color=EDGE_COLOR, line_width: float = 1.0) -> np.ndarray:
    """Render one mesh offscreen; return the picture and write it as a PNG if ``path`` is given.

    Parameters
    ----------
    mesh : Mesh
    path : str or path-like, optional
        PNG file to write.
    color : str, array or colour
        ``"curvature"``, ``"displacement"`` (needs ``reference``), ``"weights"``,
        ``"none"``, an attribute name, per-vertex or per-face values, an
        (n, 3|4) array of colours, or one colour.  See the module docstring.
    reference : Mesh, optional
        For ``color="displacement"``: the mesh before the change (same vertices).
    view : str or (azimuth, elevation)
        ``"front"``, ``"side"``, ``"back"``, ``"top"``, ``"bottom"``, ``"iso"`` or
        angles in degrees about the ``up`` axis.
    up : {"y", "z"}
        The model's up axis.
    edges : bool
        Draw every polygon's edges (quads as quads).
    size : (width, height)
        Size of the whole picture in pixels (the colour bar and label are inside it).
    shading : {"smooth", "flat"}
    colorbar : bool
        Add a colour bar under the model when colouring by a field.
    cmap : str, optional
        matplotlib colour map (default ``coolwarm`` for signed fields, else ``viridis``).
    clim : (low, high), optional
        Field range (default: robust, symmetric about 0 for signed fields).
    label : str, optional
        A title above the model.
    transparent : bool
        Return RGBA with a transparent background.

    Returns
    -------
    numpy.ndarray
        ``(height, width, 3)`` uint8 (``(height, width, 4)`` if transparent).
    """
    return render_meshes([mesh], path, grid=(1, 1), color=color, reference=reference, view=view, up=up,
                         edges=edges, size=size, shading=shading, colorbar=colorbar, cmap=cmap, clim=clim,
                         labels=None if label is None else [label], transparent=transparent,
                         curvature_area=curvature_area, edge_color=edge_color, line_width=line_width,
                         _whole_size=True)


def render_meshes(meshes: Sequence, path=None, *, grid=None, colors=None, labels=None, color="none",
                  reference=None, view="front", up: str = "y", edges: bool = False, size=(400, 400),
                  shading: str = "smooth", colorbar: bool = True, cmap: str | None = None, clim=None,
                  framing: str = "shared", transparent: bool = False, curvature_area: str = "barycentric",
                  edge_color=EDGE_COLOR, line_width: float = 1.0, _whole_size: bool = False) -> np.ndarray:
    """Render several meshes side by side, with one camera, one colour range and one colour bar.

    Parameters
    ----------
    meshes : sequence of Mesh
    path : optional PNG path
    grid : (rows, cols), optional
        Default: one row.  ``"auto"``: a near-square grid.
    colors : sequence of colours, optional
        One solid colour per mesh (overrides ``color``), e.g.
        ``family_colors(len(meshes))`` for a blue → red family strip.
    labels : sequence of str, optional
        A title above each panel.
    color : str, array, colour, or a list of those (one per mesh)
        As in :func:`render`; a field is drawn with one range shared by all panels.
    reference : Mesh or list of Mesh, optional
        Reference(s) for ``color="displacement"``.
    edges : bool or a list of bools (one per mesh)
        Draw polygon edges.
    shading : "smooth", "flat", or a list of those (one per mesh)
    size : (width, height)
        Size of each panel in pixels (label band included; the colour bar is
        added under the grid).
    framing : {"shared", "rows", "each"}
        One camera fitted to all meshes (sizes comparable), one per row of
        the grid, or one per mesh.
    color, view, up, colorbar, cmap, clim, transparent, curvature_area, edge_color, line_width
        As in :func:`render`.
    """
    meshes = list(meshes)
    k = len(meshes)
    if k == 0:
        raise ParameterError("no mesh to render")
    for i, m in enumerate(meshes):
        if not hasattr(m, "face_offsets"):
            raise ParameterError(f"item {i} is not a shapeflow Mesh but {type(m).__name__}")
        if m.n_faces == 0:
            raise ParameterError(f"nothing to render: mesh {i} has no faces")
    w, h = _check_size(size)
    shadings = list(shading) if isinstance(shading, (list, tuple)) else [shading] * k
    if len(shadings) != k or any(sh not in ("smooth", "flat") for sh in shadings):
        raise ParameterError(f"shading must be 'smooth' or 'flat' (or one of those per mesh), got {shading!r}")
    if framing not in ("shared", "rows", "each"):
        raise ParameterError(f"framing must be 'shared', 'rows' or 'each', got {framing!r}")
    _choose_backend()        # the optional dependencies first, for a clear error
    vtk = _vtk()
    _pil()
    rows, cols = _grid(grid, k)
    edge_flags = [bool(e) for e in edges] if isinstance(edges, (list, tuple)) else [bool(edges)] * k
    if len(edge_flags) != k:
        raise ParameterError(f"{len(edge_flags)} edge flags for {k} meshes")
    if labels is not None:
        labels = [str(s) for s in labels]
        if len(labels) != k:
            raise ParameterError(f"{len(labels)} labels for {k} meshes")
    refs = list(reference) if isinstance(reference, (list, tuple)) else [reference] * k
    if len(refs) != k:
        raise ParameterError(f"{len(refs)} reference meshes for {k} meshes")
    if colors is not None:
        colors = list(colors)
        if len(colors) != k:
            raise ParameterError(f"{len(colors)} colours for {k} meshes")
        specs = []
        for c in colors:
            rgb = _to_rgb(c)
            if rgb is None:
                raise ParameterError(f"not a colour: {c!r}")
            specs.append(rgb)
        fields = [_Field("solid", rgb=rgb) for rgb in specs]
    else:
        per_mesh = isinstance(color, list) and len(color) == k and not (
            k in (3, 4) and all(isinstance(x, (int, float)) for x in color))
        cs = color if per_mesh else [color] * k
        fields = [_field(m, c, r, curvature_area) for m, c, r in zip(meshes, cs, refs)]
    scalar = [f for f in fields if f.kind == "scalar"]
    diverging = bool(scalar) and all(f.diverging for f in scalar)
    if scalar:
        if clim is None and all(f.fixed for f in scalar):
            clim = (min(f.fixed[0] for f in scalar), max(f.fixed[1] for f in scalar))
        elif clim is None:
            clim = _robust_range(np.concatenate([f.values for f in scalar]), diverging)
        else:
            try:
                clim = tuple(float(x) for x in clim)
            except (TypeError, ValueError):
                raise ParameterError(f"clim must be (low, high), got {clim!r}") from None
            if len(clim) != 2 or not clim[1] > clim[0]:
                raise ParameterError(f"clim must be (low, high) with low < high, got {clim!r}")
        cmap = cmap or ("coolwarm" if diverging else "viridis")
        _colormap(cmap)  # validate early
    show_bar = colorbar and bool(scalar)
    bar_label = scalar[0].label if scalar and len({f.label for f in scalar}) == 1 else "value"

    # layout: panel = optional label band + 3D view; colour bar band under the grid
    fs_band = int(np.clip(round(min(w, h) * 0.085), 18, 40)) if labels else 0
    bar_h = _colorbar_height(cols * w) if show_bar else 0
    if _whole_size:  # render(): ``size`` is the whole picture, colour bar included
        h -= bar_h
    view_h = h - fs_band
    if view_h < 16:
        raise ParameterError(f"size {size[0]}x{size[1]} leaves no room for the model")

    aspect = w / view_h
    if framing == "shared":
        allpts = np.concatenate([m.vertices for m in meshes])
        cams = [_camera(allpts, view, up, aspect)] * k
    elif framing == "rows":
        cams = []
        for r0 in range(0, k, cols):
            row = meshes[r0:r0 + cols]
            cams += [_camera(np.concatenate([m.vertices for m in row]), view, up, aspect)] * len(row)
    else:
        cams = [_camera(m.vertices, view, up, aspect) for m in meshes]
    nch = 4 if transparent else 3
    bgpix = np.array([255, 255, 255, 0][:nch], np.uint8)
    canvas = np.empty((rows * h + bar_h, cols * w, nch), np.uint8)
    canvas[:] = bgpix
    # VTK's warnings off while we draw (offscreen drivers print harmless ones), the caller's
    # settings restored afterwards: rendering changes no process-wide state
    warn_display = vtk.vtkObject.GetGlobalWarningDisplay()
    vtk.vtkObject.GlobalWarningDisplayOff()
    win = None
    try:
        win = _Window(vtk, (w, view_h), transparent, msaa=max(m.n_faces for m in meshes) <= MSAA_MAX_FACES)
        for i, (mesh, field, cam) in enumerate(zip(meshes, fields, cams)):
            r, c = divmod(i, cols)
            actor = _actor(vtk, mesh, field, clim=clim, cmap=cmap, smooth=shadings[i] == "smooth", edges=edge_flags[i],
                           edge_color=_to_rgb(edge_color) or EDGE_COLOR, line_width=line_width)
            img = win.draw(actor, cam)
            y0, x0 = r * h, c * w
            if labels:
                canvas[y0:y0 + fs_band, x0:x0 + w] = _label_band(w, fs_band, labels[i], transparent)
            canvas[y0 + fs_band:y0 + h, x0:x0 + w] = img
    finally:
        if win is not None:
            win.close()
        vtk.vtkObject.SetGlobalWarningDisplay(warn_display)
    if show_bar:
        canvas[rows * h:, :] = _colorbar(cols * w, bar_h, cmap, clim, bar_label, diverging, transparent)
    if path is not None:
        save_png(path, canvas)
    return canvas


def _grid(grid, k: int) -> tuple[int, int]:
    if grid is None:
        return 1, k
    if isinstance(grid, str):
        if grid != "auto":
            raise ParameterError(f"grid must be (rows, cols) or 'auto', got {grid!r}")
        cols = math.ceil(math.sqrt(k))
        return math.ceil(k / cols), cols
    try:
        rows, cols = (int(x) for x in grid)
    except (TypeError, ValueError):
        raise ParameterError(f"grid must be (rows, cols), got {grid!r}") from None
    if rows < 1 or cols < 1 or rows * cols < k:
        raise ParameterError(f"a {rows}x{cols} grid cannot hold {k} meshes")
    if (rows - 1) * cols >= k or rows * (cols - 1) >= k:   # a whole empty row or column: only blank pixels
        raise ParameterError(f"grid: a {rows}x{cols} grid for {k} meshes leaves a whole row or column empty")
    return rows, cols
