"""Optional dependencies of rendering (VTK, Pillow, matplotlib's colour maps) and the offscreen OpenGL back end."""

from __future__ import annotations

import os
import sys

import numpy as np

from ..errors import OptionalDependencyError, ParameterError


class RenderBackendError(OptionalDependencyError):
    """VTK is installed but no offscreen OpenGL (EGL, OSMesa or X) is usable."""

    def __init__(self, message: str):
        ImportError.__init__(self, message)
        self.module, self.extra, self.feature, self.cause = "vtk", "render", "rendering", message

    def __reduce__(self):
        return (type(self), (str(self),))


# --------------------------------------------------------------------------
# optional dependencies and the OpenGL back end

_BACKEND_CHECKED = False
_WINDOW_CLASS: str | None = None   # the offscreen window class chosen by choose_backend (None: VTK's default)


def egl_works() -> bool:
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


def osmesa_present() -> bool:
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


def choose_backend() -> None:
    """Choose the offscreen OpenGL window class (Linux), once; the environment is not touched.

    EGL where it initialises, else OSMesa, else VTK's default window (X, with
    ``DISPLAY``).  A ``VTK_DEFAULT_OPENGL_WINDOW`` the user set is left to VTK.
    """
    global _BACKEND_CHECKED, _WINDOW_CLASS
    if _BACKEND_CHECKED:
        return
    if sys.platform.startswith("linux") and not os.environ.get("VTK_DEFAULT_OPENGL_WINDOW"):
        if egl_works():
            _WINDOW_CLASS = "vtkEGLRenderWindow"
        elif osmesa_present():
            _WINDOW_CLASS = "vtkOSOpenGLRenderWindow"
        elif not os.environ.get("DISPLAY"):
            raise RenderBackendError(
                "rendering needs offscreen OpenGL and none is usable here: install Mesa's EGL "
                "(Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) or OSMesa "
                "(libosmesa6), or set DISPLAY")
    _BACKEND_CHECKED = True


def window_class() -> str | None:
    """The offscreen window class :func:`choose_backend` picked (None: VTK's default)."""
    return _WINDOW_CLASS


def vtk_classes():
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
    except Exception as exc:   # not installed, or installed and broken (e.g. a missing libGL/libX11)
        raise OptionalDependencyError("vtk", "render", "rendering", exc) from exc
    from types import SimpleNamespace

    import vtkmodules.vtkRenderingOpenGL2 as opengl2

    return SimpleNamespace(np=numpy_support, opengl2=opengl2, vtkObject=vtkObject, vtkPoints=vtkPoints,
                           vtkLookupTable=vtkLookupTable,
                           vtkCellArray=vtkCellArray, vtkPolyData=vtkPolyData, vtkActor=vtkActor,
                           vtkLightKit=vtkLightKit, vtkPolyDataMapper=vtkPolyDataMapper,
                           vtkRenderer=vtkRenderer, vtkRenderWindow=vtkRenderWindow,
                           vtkWindowToImageFilter=vtkWindowToImageFilter)


def pil_modules():
    try:
        from PIL import Image, ImageDraw, ImageFont
    except Exception as exc:
        raise OptionalDependencyError("pillow", "render", "rendering", exc) from exc
    return Image, ImageDraw, ImageFont


def colormap(name: str):
    try:
        import matplotlib
    except Exception as exc:
        raise OptionalDependencyError("matplotlib", "render", "colour maps", exc) from exc
    try:
        return matplotlib.colormaps[name]
    except KeyError:
        raise ParameterError(f"unknown colour map {name!r} (any matplotlib colour map name)") from None


def to_rgb(spec) -> tuple[float, float, float] | None:
    """A single colour (name, '#rrggbb', RGB tuple 0..1 or 0..255), or None if spec is not one."""
    if isinstance(spec, str):
        try:
            from matplotlib.colors import to_rgb
        except Exception:
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
    choose_backend()
    vtk_classes()
    pil_modules()
    colormap("viridis")


def available() -> bool:
    """True if rendering works here (VTK importable and an offscreen OpenGL back end)."""
    try:
        require()
    except ImportError:
        return False
    return True
