"""Pictures (issue 7): render small meshes offscreen and read the PNG files back.

Skipped, with the reason, when the optional extra ``shapeflow[render]`` (VTK) is
missing or no offscreen OpenGL is usable; the error paths that need no
renderer always run.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import need
from meshgen import cube_sphere, grid

import shapeflow as sf
from shapeflow import rendering as R
from shapeflow.cli import main
from shapeflow.errors import OptionalDependencyError, ParameterError
from shapeflow.rendering import api as RA
from shapeflow.rendering import backend as RB
from shapeflow.rendering import fields as RF
from shapeflow.rendering import scene as RS

HAVE_RENDER = R.available()
needs_render = pytest.mark.skipif(
    not HAVE_RENDER,
    reason="rendering unavailable: install the extra (pip install 'shapeflow[render]') and offscreen "
           "OpenGL (Mesa EGL or OSMesa)")


def read_png(path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def object_mask(img: np.ndarray) -> np.ndarray:
    """Pixels that are not the white background."""
    return (img[..., :3].astype(int).sum(axis=2) < 3 * 245)


def bump_sphere(k: int = 20, height: float = -0.5, width: float = 0.4) -> sf.Mesh:
    """A quad sphere with a smooth bump at +z (towards the front camera); height < 0: a dent."""
    m = cube_sphere(k)
    V = m.vertices.copy()
    n = V / np.linalg.norm(V, axis=1, keepdims=True)
    ang = np.arccos(np.clip(n[:, 2], -1, 1))
    V += (height * np.exp(-(ang / width) ** 2))[:, None] * n
    return m.with_vertices(V)


def two_cubes() -> tuple[sf.Mesh, np.ndarray]:
    """A big cube at the origin and a small one behind it (at z = -3), with blue/red vertex colours."""
    base = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    V = np.vstack([base, 0.3 * base + [0.0, 0.0, -3.0]])
    F = quads + [[i + 8 for i in q] for q in quads]
    colors = np.array([[30, 60, 230]] * 8 + [[230, 20, 20]] * 8, np.uint8)
    return sf.Mesh(V, F), colors


def red_pixels(img: np.ndarray) -> int:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return int(((r > 120) & (r > b + 60) & (r > g + 60)).sum())


# --------------------------------------------------------------------------
# pictures

@needs_render
def test_png_has_the_right_size_and_shows_the_object(tmp_path):
    out = tmp_path / "sphere.png"
    img = R.render(cube_sphere(8), out, color="none", size=(320, 240))
    back = read_png(out)
    assert back.shape == (240, 320, 3) and img.shape == (240, 320, 3) and img.dtype == np.uint8
    assert np.array_equal(back, img)
    mask = object_mask(back)
    assert 0.2 < mask.mean() < 0.8                      # non-blank, not all object
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    # the sphere fills the height of the frame (it is the limiting direction), with a small margin
    assert rows.size > 0.8 * 240 and rows[0] > 0 and rows[-1] < 239
    assert abs((cols[0] + cols[-1]) / 2 - 160) < 6 and abs((rows[0] + rows[-1]) / 2 - 120) < 6  # centred


@needs_render
@pytest.mark.parametrize("view", ["front", "side", "top", "iso", (30.0, -20.0)])
def test_every_view_frames_the_object(view):
    m = sf.load_example("spot")
    img = R.render(m, None, color="none", view=view, size=(200, 160))
    mask = object_mask(img)
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    assert mask.mean() > 0.12
    assert max(rows.size / 160, cols.size / 200) > 0.8   # fitted to the tighter direction
    assert rows[0] > 0 and cols[0] > 0 and rows[-1] < 159 and cols[-1] < 199  # nothing cut off


@needs_render
def test_colours_change_where_the_curvature_changes():
    size = (300, 300)
    bumpy = R.render(bump_sphere(), None, color="curvature", view="front", size=size, colorbar=False)
    plain = R.render(cube_sphere(20), None, color="curvature", view="front", size=size, colorbar=False)
    # seen from the front the dent is in the middle: concave (blue) there, convex (red) elsewhere
    r, b = bumpy[..., 0].astype(int), bumpy[..., 2].astype(int)
    c = 150
    assert (b - r)[c - 4:c + 5, c - 4:c + 5].mean() > 60
    ys, xs = np.nonzero(object_mask(bumpy))
    far = np.hypot(ys - c, xs - c) > 100                 # the outer part of the disc: plain sphere
    assert (r - b)[ys[far], xs[far]].mean() > 30
    # a sphere has constant curvature: one colour (only shading changes)
    m = object_mask(plain)
    pr, pb = plain[..., 0].astype(int)[m], plain[..., 2].astype(int)[m]
    assert np.std(pr - pb) < 0.5 * np.std((r - b)[object_mask(bumpy)])


@needs_render
def test_hidden_surfaces_are_hidden():
    mesh, colors = two_cubes()
    front = R.render(mesh, None, color=colors, view="front", size=(200, 200))
    side = R.render(mesh, None, color=colors, view="side", size=(200, 200))
    assert red_pixels(front) == 0                        # the small red cube is behind the big blue one
    assert red_pixels(side) > 100                        # ... and visible from the side


@needs_render
def test_wireframe_draws_quads_as_quads():
    quads = grid(3, 3)                                   # 2 x 2 planar unit quads in the xy plane
    V = quads.vertices
    F = quads.face_indices.reshape(-1, 4)
    tris = sf.Mesh(V, np.concatenate([F[:, [0, 1, 2]], F[:, [0, 2, 3]]]))  # the same, cut along diagonals
    size = 240

    def diagonal_darkness(mesh):
        img = R.render(mesh, None, color="none", edges=True, view="front", size=(size, size), colorbar=False)
        lum = img.astype(float).mean(axis=2)
        mask = object_mask(img)
        rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        x0, x1, y0, y1 = cols[0], cols[-1], rows[0], rows[-1]
        dark = []
        for f in F:                                      # sample each quad's diagonals away from its edges
            p = V[f][:, :2]
            for a, c in ((0, 2), (1, 3)):
                for t in np.linspace(0.2, 0.8, 13):
                    q = p[a] + t * (p[c] - p[a])
                    px = int(round(x0 + q[0] / 2 * (x1 - x0)))
                    py = int(round(y1 - q[1] / 2 * (y1 - y0)))
                    dark.append(lum[py - 1:py + 2, px - 1:px + 2].min())
        face_lum = np.median(lum[mask])
        midline = lum[(y0 + y1) // 2, x0 + 5:x1 - 5]      # an edge line of the quad grid
        return np.array(dark), face_lum, midline.min()

    dq, face, edge = diagonal_darkness(quads)
    assert edge < face - 60                              # edges are drawn
    assert dq.min() > face - 25                          # ... but no diagonal inside a quad
    dt, face_t, _ = diagonal_darkness(tris)
    assert (dt < face_t - 60).mean() > 0.3               # control: triangles do show their diagonals


@needs_render
def test_flat_and_smooth_shading_differ():
    m = cube_sphere(3)
    smooth = R.render(m, None, color="none", shading="smooth", size=(160, 160))
    flat = R.render(m, None, color="none", shading="flat", size=(160, 160))
    assert np.abs(smooth.astype(int) - flat.astype(int)).mean() > 1.0


@needs_render
def test_side_by_side_shares_framing_and_colours(tmp_path):
    small = cube_sphere(6)
    big = small.with_vertices(2.0 * small.vertices)
    out = tmp_path / "pair.png"
    img = R.render_meshes([small, big], out, size=(200, 200), labels=["r=1", "r=2"],
                          colors=R.family_colors(2))
    assert read_png(out).shape == img.shape == (200, 400, 3)
    a, b = object_mask(img[40:, :200]).sum(), object_mask(img[40:, 200:]).sum()
    assert 2.5 < b / a < 5.0                             # same camera: the big sphere looks bigger
    left, right = img[100:, :200].reshape(-1, 3).astype(int), img[100:, 200:].reshape(-1, 3).astype(int)
    lm, rm = object_mask(img[100:, :200]).ravel(), object_mask(img[100:, 200:]).ravel()
    assert (left[lm, 2] - left[lm, 0]).mean() > 30      # first of a family is blue
    assert (right[rm, 0] - right[rm, 2]).mean() > 30    # last is red
    each = R.render_meshes([small, big], None, size=(200, 200), framing="each", color="none")
    a, b = object_mask(each[:, :200]).sum(), object_mask(each[:, 200:]).sum()
    assert 0.9 < b / a < 1.1


@needs_render
def test_grid_and_colourbar_layout():
    m = cube_sphere(6)
    img = R.render_meshes([m] * 3, None, grid="auto", size=(120, 100), color="curvature")
    assert img.shape[1] == 240 and img.shape[0] > 200   # 2 x 2 panels plus the colour bar
    single = R.render(m, None, size=(300, 200), color="curvature")
    assert single.shape == (200, 300, 3)                  # the colour bar fits inside the given size


@needs_render
def test_displacement_weights_and_arrays():
    m = cube_sphere(8)
    moved = m.with_vertices(m.vertices * 1.1)
    img = R.render(moved, None, color="displacement", reference=m, size=(160, 160), colorbar=False)
    mk = object_mask(img)
    assert (img[..., 0].astype(int) - img[..., 2].astype(int))[mk].mean() > 30   # outward: red
    w = (m.vertices[:, 0] > 0).astype(float)
    R.render(m.with_weights(w), None, color="weights", size=(120, 120))
    R.render(m, None, color=m.vertices[:, 1], size=(120, 120))                  # per-vertex values
    R.render(m, None, color=np.arange(m.n_faces, dtype=float), size=(120, 120))  # per-face values
    rgba = R.render(m, None, color="#3366cc", size=(120, 100), transparent=True)
    assert rgba.shape == (100, 120, 4) and rgba[0, 0, 3] == 0 and rgba[50, 60, 3] == 255


@needs_render
def test_open_mesh_boundary_curvature_is_neutral():
    m = grid(8, 8, z=lambda x, y: 0.05 * (x - 3.5) ** 2)
    f = RF.color_field(m, "curvature", None)
    bnd = m.topology.boundary_vertex_mask
    assert np.isnan(f.values[bnd]).all() and np.isfinite(f.values[~bnd]).all()
    img = R.render(m, None, color="curvature", view="front", size=(160, 160))
    assert object_mask(img).mean() > 0.2


# --------------------------------------------------------------------------
# errors

def test_bad_parameters_raise_parameter_error():
    m = cube_sphere(3)
    with pytest.raises(ParameterError, match="reference"):
        RF.color_field(m, "displacement", None)
    with pytest.raises(ParameterError, match="weight"):
        RF.color_field(m, "weights", None)
    with pytest.raises(ParameterError, match="unknown color"):
        RF.color_field(m, "no-such-field", None)
    with pytest.raises(ParameterError, match="values"):
        RF.color_field(m, np.zeros(m.n_vertices + 1), None)
    with pytest.raises(ParameterError, match="view"):
        RS.view_angles("sideways")
    with pytest.raises(ParameterError, match="elevation"):
        RS.view_angles((0, 120))
    with pytest.raises(ParameterError, match="size"):
        RA.check_size((4, 4000))
    with pytest.raises(ParameterError, match="grid"):
        RA.grid_shape((1, 1), 3)


def test_missing_vtk_raises_optional_dependency_error(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "vtkmodules.vtkRenderingOpenGL2", None)
    with pytest.raises(OptionalDependencyError, match=r"shapeflow\[render\]"):
        RB.vtk_classes()


def test_no_offscreen_opengl_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(RB, "_BACKEND_CHECKED", False)
    monkeypatch.setattr(RB, "egl_works", lambda: False)
    monkeypatch.setattr(RB, "osmesa_present", lambda: False)
    monkeypatch.setattr(RB.sys, "platform", "linux")
    monkeypatch.delenv("VTK_DEFAULT_OPENGL_WINDOW", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(R.RenderBackendError, match="EGL"):
        RB.choose_backend()
    with pytest.raises(OptionalDependencyError):        # the CLI turns it into exit code 2
        RB.choose_backend()


# --------------------------------------------------------------------------
# command line

@needs_render
def test_cli_render(tmp_path, capsys):
    out = tmp_path / "spot.png"
    assert main(["render", "example:spot", str(out), "--size", "320x240", "--view", "iso", "--edges"]) == 0
    assert read_png(out).shape == (240, 320, 3)
    out2 = tmp_path / "two.png"
    assert main(["render", "example:spot", "example:spot_cage", str(out2), "--size", "200x180",
                 "--color", "none", "-q"]) == 0
    assert read_png(out2).shape == (180, 400, 3)
    out3 = tmp_path / "disp.png"
    assert main(["render", "example:spot", str(out3), "--color", "displacement:example:spot",
                 "--view", "30,10", "--grid", "-q"]) == 0
    assert read_png(out3).shape[1] == 400


@pytest.mark.parametrize("argv, msg", [
    (["render", "example:spot", "OUT.jpg"], ".png"),
    (["render", "OUT.png"], "at least one mesh"),
    (["render", "example:spot", "OUT.png", "--size", "big"], "WIDTHxHEIGHT"),
    (["render", "example:spot", "OUT.png", "--color", "displacement"], "displacement:REF"),
    (["render", "example:nosuch", "OUT.png"], "nosuch"),
    (["curvature", "example:spot", "OUT.obj"], ".ply"),
])
def test_cli_errors_exit_2(tmp_path, monkeypatch, capsys, argv, msg):
    monkeypatch.chdir(tmp_path)
    if HAVE_RENDER or argv[0] == "curvature":
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert msg in err and err.count("\n") == 1 and "Traceback" not in err


def test_cli_curvature_writes_attribute(tmp_path):
    out = tmp_path / "c.ply"
    assert main(["curvature", "example:spot_cage", str(out), "--area", "mixed", "-q"]) == 0
    back = sf.load(out)
    ref = sf.mean_curvature(sf.load_example("spot_cage"), area="mixed")
    np.testing.assert_allclose(back.attributes["curvature"], ref)
    assert main(["curvature", "example:spot", str(tmp_path / "c.txt"), "-q"]) == 0
    vals = np.loadtxt(tmp_path / "c.txt")
    np.testing.assert_allclose(vals, sf.mean_curvature(sf.load_example("spot"), area="barycentric"))


@needs_render
def test_cli_curvature_image_and_render_of_attribute(tmp_path):
    out, png = tmp_path / "c.ply", tmp_path / "c.png"
    assert main(["curvature", "example:spot", str(out), "--image", str(png), "--size", "300x200", "-q"]) == 0
    assert read_png(png).shape == (200, 300, 3)
    assert main(["render", str(out), str(tmp_path / "r.png"), "--color", "curvature", "-q"]) == 0


@needs_render
@pytest.mark.parametrize("command", [["enhance", "-s", "30"], ["smooth", "-s", "5"], ["flow", "--lambda", "-10"]])
def test_cli_flow_image(tmp_path, command):
    out, png = tmp_path / "o.obj", tmp_path / "o.png"
    assert main([command[0], "example:spot", str(out), *command[1:], "--image", str(png), "-q"]) == 0
    img = read_png(png)
    assert img.shape[1] == 2 * 480 and object_mask(img).mean() > 0.1


@needs_render
def test_cli_subdivide_image(tmp_path):
    out, png = tmp_path / "s.obj", tmp_path / "s.png"
    assert main(["subdivide", "example:spot_cage", str(out), "--levels", "1", "--image", str(png)]) == 0
    img = read_png(png)
    assert img.shape[1] == 2 * 480 and object_mask(img).mean() > 0.1


def test_cli_flow_image_must_be_png(tmp_path, capsys):
    out = tmp_path / "o.obj"
    assert main(["smooth", "example:spot_cage", str(out), "-s", "1", "--image", str(tmp_path / "o.jpg"), "-q"]) == 2
    assert ".png" in capsys.readouterr().err


@needs_render
def test_image_up_axis_option(tmp_path, capsys):
    """--image-up z stands a z-up model upright: the picture is taller than wide."""
    from shapeflow.cli import main

    V = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 3], [0, 0, 3],
                  [0, 0.2, 0], [1, 0.2, 0], [1, 0.2, 3], [0, 0.2, 3]], float)
    faces = [[0, 1, 2, 3], [5, 4, 7, 6], [4, 0, 3, 7], [1, 5, 6, 2], [3, 2, 6, 7], [4, 5, 1, 0]]
    src = tmp_path / "tall_z.obj"
    sf.save(src, sf.Mesh(V, faces))
    heights = {}
    for up in ("y", "z"):
        png = tmp_path / f"{up}.png"
        assert main(["subdivide", str(src), str(tmp_path / f"o_{up}.obj"), "--levels", "1",
                     "--image", str(png), "--image-up", up]) == 0
        from PIL import Image

        a = np.asarray(Image.open(png).convert("L"))
        right = a[a.shape[0] // 8:, a.shape[1] // 2:] < 200   # the subdivided panel, below its title
        rows, cols = np.flatnonzero(right.any(axis=1)), np.flatnonzero(right.any(axis=0))
        heights[up] = (np.ptp(rows), np.ptp(cols))
    capsys.readouterr()
    assert heights["z"][0] > heights["z"][1]           # upright
    assert heights["y"][0] < heights["y"][1]           # lying down


def test_rendering_changes_no_process_wide_state(tmp_path):
    need("vtk", "VTK (the 'render' extra)")
    import os

    from vtkmodules.vtkCommonCore import vtkObject

    from shapeflow import rendering

    if not rendering.available():
        pytest.skip("rendering unavailable")
    env = dict(os.environ)
    warn = vtkObject.GetGlobalWarningDisplay()
    img = rendering.render(sf.load_example("spot"), tmp_path / "s.png", size=(160, 120))
    assert img.shape[:2] == (120, 160) and (img < 250).any()          # something was drawn
    assert dict(os.environ) == env
    assert vtkObject.GetGlobalWarningDisplay() == warn
