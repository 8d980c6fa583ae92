"""What the commands say: every line on stderr starts ``shapeflow CMD:`` (summaries, the picture's
line, the compile notice); the family's line says its shared solve in words while its report keeps
the notation; a picture that cannot be drawn (no vtk) is found out before any work, so a failed run
leaves nothing behind."""

from __future__ import annotations

import json
import sys

import pytest
from conftest import run_cli

import shapeflow as sf
from shapeflow import commands

# each command with its words: {tmp} is a fresh folder, {png} the picture it may draw, {stroke} a stroke file
COMMANDS = {
    "enhance": ["enhance", "example:spot", "{tmp}/out.ply", "-s", "5"],
    "smooth": ["smooth", "example:spot", "{tmp}/out.ply", "-s", "5"],
    "flow": ["flow", "example:spot", "{tmp}/out.ply", "--lambda", "-5"],
    "subdivide": ["subdivide", "example:spot_cage", "{tmp}/out.obj"],
    "family": ["family", "example:spot", "{tmp}/fam", "--to", "-10", "--step", "-5"],
    "brush": ["brush", "example:spot", "{tmp}/out.ply", "--stroke", "{stroke}"],
    "curvature": ["curvature", "example:spot", "{tmp}/out.ply"],
}


@pytest.fixture
def stroke(tmp_path_factory):
    path = tmp_path_factory.mktemp("stroke") / "s.json"
    spot = sf.load_example("spot")
    path.write_text(json.dumps({"lambda": -20, "radius": 0.3, "points": [spot.vertices[0].tolist()]}))
    return path


def _words(name, tmp, stroke, image):
    words = [w.format(tmp=tmp, stroke=stroke) for w in COMMANDS[name]]
    return words + (["--image", str(tmp / "x.png")] if image else [])


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_line_starts_with_the_command(tmp_path, capsys, stroke, name):
    from shapeflow import rendering

    image = rendering.available()
    code, out, err = run_cli(_words(name, tmp_path, stroke, image), capsys)
    assert code == 0, err
    lines = err.splitlines()
    assert lines and all(line.startswith(f"shapeflow {name}: ") for line in lines), err
    if image:       # the picture is named (curvature names it in its summary)
        png = tmp_path / "x.png"
        assert f"shapeflow {name}: image -> {png}" in lines or lines[-1].endswith(f", {png}")


def test_render_says_it_alike(tmp_path, capsys):
    from shapeflow import rendering

    if not rendering.available():
        pytest.skip("rendering unavailable (the render extra and offscreen OpenGL)")
    code, _, err = run_cli(["render", "example:spot", tmp_path / "r.png", "--size", "160x120"], capsys)
    assert code == 0 and err.startswith("shapeflow render: 1 mesh(es), 160x120 pixels in ") and err.count("\n") == 1


def test_the_family_says_its_shared_solve_in_words(tmp_path, capsys):
    code, _, err = run_cli(COMMANDS["family"][:2] + [tmp_path / "fam", "--to", "-10", "--step", "-5"], capsys)
    assert code == 0
    line = err.splitlines()[-1]
    assert line.startswith("shapeflow family: 3 members, λ 0 .. -10, 2930 vertices: one multi-shift CG solve for 2 "
                           "distinct |λ| (")
    assert ("(a single flow step: the members' systems are one matrix plus 1/|λ| on its diagonal, with one right-hand "
            "side, so one solve serves them all)") in line
    assert "σ" not in line and "3 members: 3 members" not in line
    said = commands.Collector()
    commands.run(commands.FamilyOptions(lam_to=-10, lam_step=-5, force=True), "example:spot", str(tmp_path / "f2"),
                 said)
    assert "(σI + M) Y = b with σ = 1/|λ|" in said.facts["reports"][0].reason


# --- a picture that cannot be drawn ---------------------------------------------------------

@pytest.fixture
def no_vtk(monkeypatch):
    """vtk missing, as on an install without the render extra (the offscreen back end taken as chosen)."""
    from shapeflow.rendering import backend

    monkeypatch.setattr(backend, "_BACKEND_CHECKED", True)
    for name in [m for m in sys.modules if m == "vtkmodules" or m.startswith("vtkmodules.")] + ["vtkmodules"]:
        monkeypatch.setitem(sys.modules, name, None)       # import raises ModuleNotFoundError


@pytest.mark.parametrize("name", sorted(COMMANDS) + ["render"])
def test_without_vtk_an_image_fails_before_any_work(tmp_path, capsys, stroke, no_vtk, name):
    words = ["render", "example:spot", str(tmp_path / "x.png")] if name == "render" else \
        _words(name, tmp_path, stroke, True)
    code, out, err = run_cli(words, capsys)
    assert (code, out) == (2, "")
    assert err.startswith(f"shapeflow {name}: error: rendering needs the optional package 'vtk' (") and \
        err.endswith("): pip install 'shapeflow[render]'\n") and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


def test_the_newcomer_s_command(tmp_path, capsys, no_vtk, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(["enhance", "example:spot", "p.ply", "-s", "5", "--image", "x.png"], capsys)
    assert code == 2 and "vtk" in err and not (tmp_path / "p.ply").exists() and not (tmp_path / "x.png").exists()
