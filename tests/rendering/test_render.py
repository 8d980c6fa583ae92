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


# --------------------------------------------------------------------------
# the view convention (Blender's) and clipped colour ranges

def test_named_views_are_blenders_from_the_models_front():
    """Front looks at the side the model faces, right from its right (+x in Blender's frame), top from
    above; z up is Blender's frame (front faces -y), y up is turned as Blender's importers turn it."""
    from shapeflow.rendering.style import frame

    pts = np.array([[-1.0, -1, -1], [1, 1, 1]])
    def seen_from(view, up="y", front=None):
        cam = RS.camera(pts, view, up, 1.0, front=front)
        d = np.asarray(cam.position) - np.asarray(cam.target)
        return np.round(d / np.linalg.norm(d), 9)

    assert seen_from("front", "z").tolist() == [0, -1, 0]            # Blender: the front view looks along +y
    assert seen_from("right", "z").tolist() == [1, 0, 0]
    assert seen_from("top", "z").tolist() == [0, 0, 1]
    assert seen_from("front", "y").tolist() == [0, 0, 1]              # y up: Blender's (x, -z, y)
    assert seen_from("back", "y").tolist() == [0, 0, -1] and seen_from("left", "y").tolist() == [-1, 0, 0]
    assert seen_from((0.0, 0.0), "y").tolist() == seen_from("front", "y").tolist()
    assert seen_from((90.0, 0.0), "y").tolist() == seen_from("right", "y").tolist()
    assert seen_from("front", "y", "-z").tolist() == [0, 0, -1]       # a model that faces -z
    assert seen_from("right", "y", "-z").tolist() == [-1, 0, 0]       # its right: up × front
    R_, U, F = frame("y", "-z")
    assert np.array_equal(R_, np.cross(U, F))
    with pytest.raises(ParameterError, match="front must be one of"):
        frame("y", "forward")
    with pytest.raises(ParameterError, match="along the up axis"):
        frame("z", "+z")


def test_the_bundled_spot_says_which_way_it_faces():
    spot = sf.load_example("spot")
    V = spot.vertices
    snout = V[:, 2] < V[:, 2].min() + 0.2 * np.ptp(V[:, 2])       # the part furthest towards -z ...
    assert V[snout, 1].mean() > V[:, 1].mean() + 0.3               # ... is high up: the head
    assert abs(V[snout, 0].mean()) < 1e-9                          # and centred: the face, not a leg
    assert spot.metadata["front"] == "-z" and sf.load_example("spot_cage").metadata["front"] == "-z"


def _visible_fraction_from_geometry(V, region, towards: int, n: int = 15) -> float:
    """The share of an n × n grid over the xy extent whose nearest vertex, seen from z = towards·∞,
    lies in ``region``: an orthographic point z-buffer from the positions alone."""
    lo, hi = V[:, :2].min(axis=0), V[:, :2].max(axis=0)
    ij = np.floor((V[:, :2] - lo) / (hi - lo) * (n - 1e-9)).astype(int)
    key = ij[:, 0] * n + ij[:, 1]
    order = np.lexsort((-towards * V[:, 2], key))
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    return float(region[order][first].mean())


@needs_render
def test_the_default_view_of_spot_shows_its_face(tmp_path):
    spot = sf.load_example("spot")
    V = spot.vertices
    snout = V[:, 2] < V[:, 2].min() + 0.2 * np.ptp(V[:, 2])
    expect_front = _visible_fraction_from_geometry(V, snout, towards=-1)     # the camera on the -z side
    expect_back = _visible_fraction_from_geometry(V, snout, towards=+1)
    assert expect_front > 0.3 and expect_back < 0.05
    colors = np.where(snout[:, None], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])

    def snout_share(img):
        r, b = img[..., 0].astype(int), img[..., 2].astype(int)
        red, blue = int((r > b + 60).sum()), int((b > r + 60).sum())
        return red / (red + blue)

    default = R.render(spot, None, color=colors, size=(200, 160), colorbar=False)
    assert abs(snout_share(default) - expect_front) < 0.15
    assert snout_share(R.render(spot, None, color=colors, view="back", size=(200, 160), colorbar=False)) < 0.05
    # the command line: the default and --view 0,0 are the same picture, the front
    assert main(["render", "example:spot", str(tmp_path / "a.png"), "--size", "200x160", "-q"]) == 0
    assert main(["render", "example:spot", str(tmp_path / "b.png"), "--size", "200x160", "-q", "--view", "0,0"]) == 0
    assert np.array_equal(read_png(tmp_path / "a.png"), read_png(tmp_path / "b.png"))
    # seen from its right, the head is on the left of the picture
    right = R.render(spot, None, color=colors, view="right", size=(200, 160), colorbar=False).astype(int)
    cols = np.nonzero(right[..., 0] > right[..., 2] + 60)[1]
    assert cols.mean() < 0.4 * right.shape[1]


def test_legend_ends_say_where_the_data_pass_the_range():
    from shapeflow.rendering.overlay import tick_labels

    assert tick_labels((-19.0, 19.0), True, (-87.0, 71.0)) == [(-19.0, "≤ -19"), (0.0, "0"), (19.0, "≥ 19")]
    assert tick_labels((-19.0, 19.0), True, (-5.0, 19.0)) == [(-19.0, "-19"), (0.0, "0"), (19.0, "19")]
    assert tick_labels((0.0, 1.0), False, (0.0, 3.0)) == [(0.0, "0"), (1.0, "≥ 1")]


@needs_render
def test_a_clipped_legend_draws_its_ends():
    """A field from -87 to 71 drawn with the range ±19: both ends of the bar get a triangle in the
    end's colour (dark blue left, dark red right); an unclipped one has none."""
    mesh = grid(12, 12)
    values = np.linspace(-87.0, 71.0, mesh.n_vertices)
    clipped = R.render(mesh, None, color=values, clim=(-19, 19), size=(400, 300))
    plain = R.render(mesh, None, color=values, clim=(-87, 87), size=(400, 300))
    band = slice(300 - RA.colorbar_height(400), 300)

    def coloured_columns(img):
        r, g, b = (img[band, :, i].astype(int) for i in range(3))
        return np.nonzero(((b > r + 80) | (r > b + 80)).any(axis=0))[0]

    bar = coloured_columns(plain)
    ends = coloured_columns(clipped)
    assert ends.min() < bar.min() - 3 and ends.max() > bar.max() + 3   # triangles beyond both ends
