"""Feature lines in pictures: ``render(..., feature_lines=...)`` draws the sharp edges over the surface.

Where lines must be is derived from the geometry: the cube's twelve edges are projected through a
pinhole camera built here from the camera the renderer placed (position, target, up, vertical view
angle); an edge is visible when one of its two faces faces the camera (the cube is convex).  Pixels
of the line colour must lie along the visible edges' projections, and nowhere else.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import shapeflow as sf
from shapeflow import rendering as R
from shapeflow.errors import ParameterError
from shapeflow.geometry.features import angle_sharp_edges
from shapeflow.rendering import scene as RS

HAVE_RENDER = R.available()
needs_render = pytest.mark.skipif(
    not HAVE_RENDER,
    reason="rendering unavailable: install the extra (pip install 'shapeflow[render]') and offscreen "
           "OpenGL (Mesa EGL or OSMesa)")
SIZE = 320
VIEW = (35.0, 25.0)
RED = (0.9, 0.1, 0.1)


def box(half: float = 1.0) -> sf.Mesh:
    return sf.Mesh([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)],
                   [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])


def grid_cube() -> sf.Mesh:
    """The cube [-1, 1]³ with every side a 4 × 4 grid: many edges, twelve of them sharp."""
    return sf.subdivide(box(), 2, scheme="simple")


def red_mask(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return (r > 150) & (r - g > 90) & (r - b > 90)


def project(points, cam: RS.Camera, w: int, h: int) -> np.ndarray:
    """Pixel (column, row) of each 3D point through a pinhole camera (vertical view angle)."""
    pos, target = np.asarray(cam.position, float), np.asarray(cam.target, float)
    f = (target - pos) / np.linalg.norm(target - pos)
    u = np.asarray(cam.up, float)
    u = u - (u @ f) * f
    u /= np.linalg.norm(u)
    r = np.cross(f, u)
    d = np.asarray(points, float) - pos
    t = math.tan(math.radians(cam.angle) / 2)
    x = (d @ r) / ((d @ f) * t * (w / h))
    y = (d @ u) / ((d @ f) * t)
    return np.c_[(x + 1) / 2 * w - 0.5, (1 - y) / 2 * h - 0.5]


def cube_edges_seen(cam: RS.Camera):
    """The twelve edges of [-1, 1]³ as (a, b) corner pairs, and whether each is visible from the camera."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    pos = np.asarray(cam.position, float)
    out = []
    for i in range(8):
        for j in range(i + 1, 8):
            diff = corners[j] - corners[i]
            if np.count_nonzero(diff) != 1:
                continue
            axis = int(np.flatnonzero(diff)[0])
            seen = False
            for k in range(3):        # the edge's two faces: normals along the two other axes
                if k == axis:
                    continue
                n = np.zeros(3)
                n[k] = corners[i][k]
                seen |= bool(n @ (pos - corners[i]) > 0)
            out.append((corners[i], corners[j], seen))
    return out


def seg_distance(p, a, b) -> np.ndarray:
    """Distance of the 2D points p (m, 2) from the segment a–b."""
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


@needs_render
def test_lines_are_drawn_along_the_visible_sharp_edges_only():
    cube = grid_cube()
    img = R.render(cube, None, color="none", view=VIEW, size=(SIZE, SIZE), colorbar=False, feature_lines=30.0,
                   feature_color=RED, feature_width=3.0)
    cam = RS.camera(cube.vertices, VIEW, "y", 1.0)
    red = red_mask(img)
    edges = cube_edges_seen(cam)
    assert sum(seen for *_, seen in edges) == 9                     # three sides face the camera
    visible = [(project(a[None], cam, SIZE, SIZE)[0], project(b[None], cam, SIZE, SIZE)[0])
               for a, b, seen in edges if seen]
    # every visible edge is drawn along its whole length
    for (a, b, seen) in edges:
        for t in np.linspace(0.1, 0.9, 9):
            c, r = np.rint(project([a + t * (b - a)], cam, SIZE, SIZE)[0]).astype(int)
            near = red[r - 2:r + 3, c - 2:c + 3].any()
            if seen:
                assert near, (a, b, t)
            elif min(seg_distance(np.array([[c, r]], float), p, q)[0] for p, q in visible) > 6:
                assert not red[r - 1:r + 2, c - 1:c + 2].any(), (a, b, t)   # hidden behind the sides
    # and nothing else: every line pixel lies on a visible edge's projection (line width + antialiasing)
    rows, cols = np.nonzero(red)
    pix = np.c_[cols, rows].astype(float)
    dist = np.min([seg_distance(pix, p, q) for p, q in visible], axis=0)
    assert red.sum() > 9 * 40 and dist.max() <= 3.0, dist.max()
    # the inner grid lines of the sides (not sharp) are not drawn
    plain = R.render(cube, None, color="none", view=VIEW, size=(SIZE, SIZE), colorbar=False)
    assert not red_mask(plain).any()


@needs_render
def test_vtk_coincident_topology_mode_is_restored():
    """The polygon offset the lines need is VTK's process-wide setting: on while a picture with lines is
    drawn, the caller's afterwards."""
    from vtkmodules.vtkRenderingCore import VTK_RESOLVE_SHIFT_ZBUFFER, vtkMapper

    before = vtkMapper.GetResolveCoincidentTopology()
    R.render(grid_cube(), None, color="none", size=(64, 64), colorbar=False, feature_lines=30.0)
    assert vtkMapper.GetResolveCoincidentTopology() == before
    vtkMapper.SetResolveCoincidentTopologyToShiftZBuffer()
    try:
        R.render(grid_cube(), None, color="none", size=(64, 64), colorbar=False, feature_lines=30.0)
        assert vtkMapper.GetResolveCoincidentTopology() == VTK_RESOLVE_SHIFT_ZBUFFER
    finally:
        vtkMapper.SetResolveCoincidentTopology(before)


@needs_render
def test_the_ways_to_name_the_edges_draw_the_same_lines():
    cube = grid_cube()
    kw = dict(color="none", view=VIEW, size=(200, 200), colorbar=False)
    by_angle = R.render(cube, None, feature_lines=30.0, **kw)
    assert (by_angle.max(axis=2) < 40).sum() > 100               # the default colour is black
    sharp = cube.topology.edges[angle_sharp_edges(cube, 30.0)]
    assert len(sharp) == 12 * 4
    assert np.array_equal(R.render(cube, None, feature_lines=sharp, **kw), by_angle)
    assert np.array_equal(R.render(cube, None, feature_lines=True, **kw), by_angle)       # 30°
    # "mesh": a subdivision's creases; infinitely sharp on every edge of a box, the result is the same cube
    creased = sf.subdivide(box(), 2, creases=(box().topology.edges, 1.0))
    assert np.abs(creased.vertices - cube.vertices).max() < 1e-12
    assert np.array_equal(R.render(creased, None, feature_lines="mesh", **kw), by_angle)
    # a mesh marking nothing, or an angle no edge passes: no line
    assert np.array_equal(R.render(cube, None, feature_lines="mesh", **kw), R.render(cube, None, **kw))
    assert np.array_equal(R.render(cube, None, feature_lines=91.0, **kw), R.render(cube, None, **kw))


@needs_render
def test_one_choice_per_panel():
    cube = grid_cube()
    img = R.render_meshes([cube, cube], None, color="none", view=VIEW, size=(160, 160), colorbar=False,
                          feature_lines=[30.0, None], feature_color=RED)
    red = red_mask(img)
    assert red[:, :160].sum() > 100 and not red[:, 160:].any()
    pairs = cube.topology.edges[:5]                              # a list of pairs is one choice for all
    both = R.render_meshes([cube, cube], None, color="none", view=VIEW, size=(160, 160), colorbar=False,
                           feature_lines=pairs.tolist(), feature_color=RED)
    assert np.array_equal(both[:, :160], both[:, 160:])


def test_bad_feature_lines_raise_parameter_error():
    cube = grid_cube()
    if not HAVE_RENDER:
        pytest.skip("the checks run after the renderer is found")
    cases = [
        (dict(feature_lines="sharp"), "feature_lines must be"),
        (dict(feature_lines=200.0), "feature_lines must be <= 180"),
        (dict(feature_lines=[[0, cube.n_vertices + 3]]), "feature_lines: row 0"),
        (dict(feature_lines=[[0, 1], [0, 2]]), "is not an edge"),
        (dict(feature_lines=np.arange(6)), "shape"),
        (dict(feature_lines=30.0, feature_color="not-a-colour"), "feature_color"),
        (dict(feature_lines=30.0, feature_width=0.0), "feature_width"),
    ]
    for kw, msg in cases:
        with pytest.raises(ParameterError, match=msg):
            R.render(cube, None, color="none", size=(64, 64), **kw)
