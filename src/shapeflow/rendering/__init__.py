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
* ``feature_lines=`` draws sharp edges as lines over the surface, hidden ones
  hidden (:mod:`.lines`): those whose faces bend by more than a feature angle
  (``30``, or ``True`` for 30°), those the mesh marks (``"mesh"``: smoothing
  groups, crease tags, a subdivision's creases), or given vertex pairs; one
  choice for all panels or one per mesh, in ``feature_color`` (black)
  ``feature_width`` pixels wide.
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


from .api import family_colors, render, render_meshes, save_png
from .backend import RenderBackendError, available, require
from .style import VIEWS

__all__ = ["render", "render_meshes", "family_colors", "available", "require", "save_png",
           "RenderBackendError", "VIEWS"]
