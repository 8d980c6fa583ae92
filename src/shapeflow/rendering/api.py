"""Pictures of meshes: :func:`render` (one mesh) and :func:`render_meshes` (a grid of panels)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from ..errors import ParameterError
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from ..types import Color, PathLike, Size, View
from .backend import choose_backend, colormap, pil_modules, to_rgb, vtk_classes
from .fields import Field, color_field, robust_range
from .lines import FeatureLines, PanelLines
from .overlay import colorbar_height, colorbar_image, label_band
from .scene import Window, camera, make_actor
from .style import EDGE_COLOR, FEATURE_COLOR, MSAA_MAX_FACES


def save_png(path, image: np.ndarray, *, force: bool = False) -> None:
    """Write an (h, w, 3|4) uint8 array as a PNG, atomically (:func:`shapeflow.io.atomic_write`)."""
    from ..io import atomic_write

    Image, _, _ = pil_modules()
    atomic_write(os.fspath(path), lambda f: Image.fromarray(image).save(f, format="PNG"), force=force)


def check_size(size) -> tuple[int, int]:
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
    c = colormap(cmap)(np.linspace(0.0, 1.0, n) if n > 1 else [0.0])
    return [tuple(float(x) for x in row[:3]) for row in c]


# --------------------------------------------------------------------------
# public API

def render(mesh: Mesh, path: PathLike | None = None, *, color: Color = "curvature", reference: Mesh | None = None,
           view: View = "front", up: str = "y", front: str | None = None, edges: bool = False,
           size: Size = (800, 600),
           shading: str = "smooth", colorbar: bool = True, cmap: str | None = None,
           clim: Sequence[float] | None = None, label: str | None = None, transparent: bool = False,
           curvature_area: str = "barycentric", edge_color: Color = EDGE_COLOR,
           line_width: float = 1.0, feature_lines: FeatureLines = None, feature_color: Color = FEATURE_COLOR,
           feature_width: float = 2.5) -> np.ndarray:
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
        ``"front"``, ``"back"``, ``"left"``, ``"right"``, ``"top"``, ``"bottom"``, ``"iso"``
        (``"side"`` = ``"right"``) or angles in degrees from the model's front: azimuth about the
        ``up`` axis towards the right, elevation towards the top.  Blender's convention: the
        front view looks at the side the model faces (docs/cli.md, "Views").
    up : {"y", "z"}
        The model's up axis.
    front : {"+z", "-z", "+x", "-x", "+y", "-y"}, optional
        The axis the model faces.  Default: the mesh's ``metadata["front"]`` (the bundled Spot
        faces ``"-z"``), else ``"+z"`` for ``up="y"`` (glTF's and Blender's exporters' convention)
        and ``"-y"`` for ``up="z"`` (Blender's own frame).
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
    feature_lines : float, True, "mesh" or (k, 2) array, optional
        Draw sharp edges as lines over the surface: those whose two faces bend by more than
        this many degrees (``True``: 30°), those the mesh marks (``"mesh"``: smoothing-group
        borders, crease tags, a subdivision's creases), or the given vertex pairs.  Hidden
        ones stay hidden.
    feature_color, feature_width
        The lines' colour and width in pixels.

    Returns
    -------
    numpy.ndarray
        ``(height, width, 3)`` uint8 (``(height, width, 4)`` if transparent).
    """
    return render_meshes([mesh], path, grid=(1, 1), color=color, reference=reference, view=view, up=up, front=front,
                         edges=edges, size=size, shading=shading, colorbar=colorbar, cmap=cmap, clim=clim,
                         labels=None if label is None else [label], transparent=transparent,
                         curvature_area=curvature_area, edge_color=edge_color, line_width=line_width,
                         feature_lines=feature_lines, feature_color=feature_color, feature_width=feature_width,
                         _whole_size=True)


def render_meshes(meshes: Sequence[Mesh], path: PathLike | None = None, *,
                  grid: tuple[int, int] | str | None = None, colors: Sequence[Color] | None = None,
                  labels: Sequence[str] | None = None, color: Color | list = "none",
                  reference: Mesh | Sequence[Mesh] | None = None, view: View = "front", up: str = "y",
                  front: str | None = None,
                  edges: bool | Sequence[bool] = False, size: Size = (400, 400),
                  shading: str | Sequence[str] = "smooth", colorbar: bool = True, cmap: str | None = None,
                  clim: Sequence[float] | None = None, framing: str = "shared", transparent: bool = False,
                  curvature_area: str = "barycentric", edge_color: Color = EDGE_COLOR, line_width: float = 1.0,
                  feature_lines: FeatureLines | list = None, feature_color: Color = FEATURE_COLOR,
                  feature_width: float = 2.5,
                  _whole_size: bool = False) -> np.ndarray:
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
    feature_lines : as in :func:`render`, or a list with one of those per mesh
        Sharp edges drawn as lines (a list of vertex pairs is one choice for every mesh).
    color, view, up, front, colorbar, cmap, clim, transparent, curvature_area, edge_color, line_width,
    feature_color, feature_width
        As in :func:`render` (the first mesh's ``metadata["front"]`` when ``front`` is not given).
    """
    meshes = list(meshes)
    k = len(meshes)
    if k == 0:
        raise ParameterError("no mesh to render")
    meshes = [as_mesh(m, f"item {i}") for i, m in enumerate(meshes)]
    for i, m in enumerate(meshes):
        if m.n_faces == 0:
            raise ParameterError(f"nothing to render: mesh {i} has no faces")
    w, h = check_size(size)
    shadings = list(shading) if isinstance(shading, (list, tuple)) else [shading] * k
    if len(shadings) != k or any(sh not in ("smooth", "flat") for sh in shadings):
        raise ParameterError(f"shading must be 'smooth' or 'flat' (or one of those per mesh), got {shading!r}")
    if framing not in ("shared", "rows", "each"):
        raise ParameterError(f"framing must be 'shared', 'rows' or 'each', got {framing!r}")
    choose_backend()        # the optional dependencies first, for a clear error
    vtk = vtk_classes()
    pil_modules()
    rows, cols = grid_shape(grid, k)
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
    fields = panel_fields(meshes, colors, color, refs, curvature_area)
    lines = PanelLines(meshes, feature_lines, feature_color, feature_width)
    edge_rgb = to_rgb(edge_color) or EDGE_COLOR
    scalar = [f for f in fields if f.kind == "scalar"]
    diverging = bool(scalar) and all(f.diverging for f in scalar)
    if scalar:
        clim, cmap = shared_range(scalar, clim, cmap, diverging)
    show_bar = colorbar and bool(scalar)
    bar_label = scalar[0].label if scalar and len({f.label for f in scalar}) == 1 else "value"

    # layout: panel = optional label band + 3D view; colour bar band under the grid
    fs_band = int(np.clip(round(min(w, h) * 0.085), 18, 40)) if labels else 0
    bar_h = colorbar_height(cols * w) if show_bar else 0
    if _whole_size:  # render(): ``size`` is the whole picture, colour bar included
        h -= bar_h
    view_h = h - fs_band
    if view_h < 16:
        raise ParameterError(f"size {size[0]}x{size[1]} leaves no room for the model")

    if front is None:
        front = meshes[0].metadata.get("front")
    cams = cameras(meshes, framing, view, up, w / view_h, cols, front)
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
        win = Window(vtk, (w, view_h), transparent, msaa=max(m.n_faces for m in meshes) <= MSAA_MAX_FACES)
        for i, (mesh, field, cam) in enumerate(zip(meshes, fields, cams)):
            r, c = divmod(i, cols)
            shape = make_actor(vtk, mesh, field, clim=clim, cmap=cmap, smooth=shadings[i] == "smooth",
                               edges=edge_flags[i], edge_color=edge_rgb, line_width=line_width)
            img = win.draw([shape, *lines.actors(vtk, i)], cam)
            y0, x0 = r * h, c * w
            if labels:
                canvas[y0:y0 + fs_band, x0:x0 + w] = label_band(w, fs_band, labels[i], transparent)
            canvas[y0 + fs_band:y0 + h, x0:x0 + w] = img
    finally:
        if win is not None:
            win.close()
        vtk.vtkObject.SetGlobalWarningDisplay(warn_display)
    if show_bar:
        canvas[rows * h:, :] = colorbar_image(cols * w, bar_h, cmap, clim, bar_label, diverging, transparent,
                                              data_range=field_extent(scalar))
    if path is not None:
        save_png(path, canvas)
    return canvas


def panel_fields(meshes: list, colors, color, refs: list, curvature_area: str) -> list:
    """What each panel paints: one solid colour per mesh (``colors``), else ``color`` (shared or per mesh)."""
    k = len(meshes)
    if colors is not None:
        colors = list(colors)
        if len(colors) != k:
            raise ParameterError(f"{len(colors)} colours for {k} meshes")
        specs = []
        for c in colors:
            rgb = to_rgb(c)
            if rgb is None:
                raise ParameterError(f"not a colour: {c!r}")
            specs.append(rgb)
        return [Field("solid", rgb=rgb) for rgb in specs]
    per_mesh = isinstance(color, list) and len(color) == k and not (
        k in (3, 4) and all(isinstance(x, (int, float)) for x in color))
    cs = color if per_mesh else [color] * k
    return [color_field(m, c, r, curvature_area) for m, c, r in zip(meshes, cs, refs)]


def field_extent(scalar: list) -> tuple[float, float] | None:
    """The smallest and largest finite value of the fields (None: no finite value)."""
    vals = np.concatenate([np.asarray(f.values, dtype=np.float64).ravel() for f in scalar])
    vals = vals[np.isfinite(vals)]
    return (float(vals.min()), float(vals.max())) if vals.size else None


def shared_range(scalar: list, clim, cmap, diverging: bool):
    """One colour range and colour map for every scalar field (``clim`` checked when given)."""
    if clim is None and all(f.fixed for f in scalar):
        clim = (min(f.fixed[0] for f in scalar), max(f.fixed[1] for f in scalar))
    elif clim is None:
        clim = robust_range(np.concatenate([f.values for f in scalar]), diverging)
    else:
        try:
            clim = tuple(float(x) for x in clim)
        except (TypeError, ValueError):
            raise ParameterError(f"clim must be (low, high), got {clim!r}") from None
        if len(clim) != 2 or not clim[1] > clim[0]:
            raise ParameterError(f"clim must be (low, high) with low < high, got {clim!r}")
    cmap = cmap or ("coolwarm" if diverging else "viridis")
    colormap(cmap)  # validate early
    return clim, cmap


def cameras(meshes: list, framing: str, view, up: str, aspect: float, cols: int, front: str | None = None) -> list:
    """One camera per panel: fitted to all meshes, to each row of the grid, or to each mesh."""
    k = len(meshes)
    if framing == "shared":
        allpts = np.concatenate([m.vertices for m in meshes])
        return [camera(allpts, view, up, aspect, front=front)] * k
    if framing == "rows":
        cams = []
        for r0 in range(0, k, cols):
            row = meshes[r0:r0 + cols]
            cams += [camera(np.concatenate([m.vertices for m in row]), view, up, aspect, front=front)] * len(row)
        return cams
    return [camera(m.vertices, view, up, aspect, front=front) for m in meshes]


def grid_shape(grid, k: int) -> tuple[int, int]:
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
