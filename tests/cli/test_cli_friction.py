"""What a new user ran into: warnings for λ so large the result says little, one name for the
picture's up axis, the family picture described as it is, point clouds refused."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import need

import shapeflow as sf
from shapeflow.cli import main


@pytest.mark.parametrize("cmd,strength,expect", [
    ("smooth", "1e6", "collapsed the model"),
    ("enhance", "1e6", "mostly rescaled the model (by 2"),   # the limit: V + (V - mean), a scale by 2
    ("enhance", "20", None),
    ("smooth", "2", None),
])
def test_extreme_strengths_are_named(tmp_path, capsys, cmd, strength, expect):
    out = tmp_path / "out.ply"
    assert main([cmd, "example:spot", str(out), "--strength", strength]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    if expect is None:
        assert warned == []
    else:
        assert len(warned) == 1 and expect in warned[0]
        # the claim checked on the written file
        m, r = sf.load_example("spot"), sf.load(out)
        if cmd == "smooth":
            assert r.diagonal < 0.05 * m.diagonal
        else:   # a uniform scale about some point: least squares X = s V + t, small residual
            A = np.zeros((3 * m.n_vertices, 4))
            A[:, 0] = m.vertices.reshape(-1)
            A[np.arange(3 * m.n_vertices), 1 + np.arange(3 * m.n_vertices) % 3] = 1.0
            sol, *_ = np.linalg.lstsq(A, r.vertices.reshape(-1), rcond=None)
            resid = np.linalg.norm(A @ sol - r.vertices.reshape(-1))
            assert abs(sol[0] - 2.0) < 0.02 and resid < 0.05 * np.linalg.norm(r.vertices - m.vertices)


def test_up_is_an_alias_of_image_up():
    from shapeflow.cli import build_parser

    p = build_parser()
    a = p.parse_args(["smooth", "example:spot", "o.ply", "--strength", "1", "--up", "z"])
    b = p.parse_args(["smooth", "example:spot", "o.ply", "--strength", "1", "--image-up", "z"])
    assert a.image_up == b.image_up == "z"


def test_family_help_describes_its_picture(capsys):
    assert main(["family", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "strip of up to 12 members" in out and "side by side" not in out


def test_no_compile_notice_when_the_kernels_are_off(capsys):
    from shapeflow import accel
    from shapeflow.commands import Collector
    from shapeflow.commands.common import note_compiling

    said = Collector()
    with accel.use(kernels="off"):
        assert note_compiling(said, ("sculpt",), 10**6) is False
    assert said.messages == [] and capsys.readouterr().err == ""


def test_the_up_axis_follows_the_file_convention():
    from shapeflow.commands.images import up_axis

    tri = sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]], [[0, 1, 2]])
    stl = tri.with_metadata(stl={"name": "part"})
    assert up_axis("auto", tri) == "y" and up_axis("auto", stl) == "z"
    assert up_axis("y", stl) == "y" and up_axis("z", tri) == "z"


def test_the_render_command_takes_the_models_front(tmp_path):
    """The command's default view is the library's for the same mesh: the bundled Spot's front (-z);
    --front +z (the convention for y-up files that name none) shows its back."""
    need("vtk", "VTK (the 'render' extra)")
    from shapeflow.rendering import available, render

    if not available():
        pytest.skip("no offscreen OpenGL here")
    spot = sf.load_example("spot")
    size = dict(size=(200, 160), colorbar=False)
    for extra, front in (([], None), (["--front", "+z"], "+z"), (["--view", "right"], None)):
        out = tmp_path / "spot.png"
        view = "right" if "right" in extra else "front"
        assert main(["render", "example:spot", str(out), "--size", "200x160", "--no-colorbar", "-q", *extra]) == 0
        from PIL import Image

        img = np.asarray(Image.open(out).convert("RGB")).astype(int)
        want = render(spot, None, view=view, front=front, **size)[:, :, :3].astype(int)
        assert np.abs(img - want).max() <= 1
    back = render(spot, None, view="back", **size)[:, :, :3].astype(int)
    assert np.abs(render(spot, None, front="+z", **size)[:, :, :3].astype(int) - back).max() <= 1
