"""Option values as a user writes them: a value that starts with '-' (``--front -z``, as docs/cli.md's
Views tell) is the option's when it is one of its choices; an option whose value may be left out
(``--feature-lines [DEG|marked]``, ``--grid [RxC]``) takes the next word only if it is one of its
values, so paths around it stay paths; the words of a render may come before and after its options."""

from __future__ import annotations

import pytest
from conftest import run_cli

from shapeflow.commands import operations_parser, options_from
from shapeflow.errors import ParameterError


@pytest.mark.parametrize("words,front", [
    (["--front", "-z"], "-z"),
    (["--front", "-x"], "-x"),
    (["--front", "-y"], "-y"),
    (["--front", "+x"], "+x"),
    (["--front=-z"], "-z"),
    (["--fro", "-z"], "-z"),                     # an abbreviation, as argparse takes them
    (["--front", "-z", "--up", "y"], "-z"),
    ([], "auto"),
])
def test_front_takes_a_value_that_starts_with_a_dash(words, front):
    for order in (["render", "spot.obj", "r.png", *words], ["render", *words, "spot.obj", "r.png"]):
        args = operations_parser().parse_args(order)
        assert (args.front, args.input, args.output) == (front, ["spot.obj"], "r.png")


@pytest.mark.parametrize("words,up", [
    (["render", "a.stl", "r.png", "--up", "z"], "z"),
    (["render", "--up", "y", "a.stl", "r.png"], "y"),
])
def test_up_is_read_as_before(words, up):
    assert operations_parser().parse_args(words).up == up


def test_the_image_up_of_the_flow_commands(tmp_path):
    args = operations_parser().parse_args(["enhance", "a.ply", "b.ply", "-s", "5", "--up", "z", "--image", "x.png"])
    assert (args.image_up, args.image, args.output) == ("z", "x.png", "b.ply")


@pytest.mark.parametrize("words,line", [
    (["--front", "-q"], "--front needs a value"),
    (["--front", "--edges"], "--front needs a value"),
    (["--front", "-Z"], "--front must be one of auto, +x, -x, +y, -y, +z, -z, got '-Z'; did you mean -z?"),
    (["--front", "-w"], "--front must be one of auto, +x, -x, +y, -y, +z, -z, got '-w'"),
    (["--front", "z"], "--front must be one of auto, +x, -x, +y, -y, +z, -z, got 'z'; did you mean +z?"),
    (["--up", "-z"], "--up must be one of auto, y, z, got '-z'; did you mean z?"),
])
def test_a_bad_value_is_told_as_one(tmp_path, capsys, words, line):
    code, out, err = run_cli(["render", "example:spot", tmp_path / "r.png", *words], capsys)
    assert (code, out, err) == (2, "", f"shapeflow render: error: {line} (see 'shapeflow render --help')\n")
    assert list(tmp_path.iterdir()) == []


def test_a_word_after_feature_lines_that_is_no_value_is_a_path(tmp_path, capsys):
    code, out, err = run_cli(["render", "example:spot", tmp_path / "r.png", "--feature-lines", "sharp"], capsys)
    assert (code, out, err) == (2, "", "shapeflow render: error: output 'sharp' must be a .png file\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("words,lines,inputs", [
    (["render", "spot.ply", "--feature-lines", "fl.png"], 30.0, ["spot.ply"]),
    (["render", "spot.ply", "--feature-lines", "marked", "fl.png"], "marked", ["spot.ply"]),
    (["render", "spot.ply", "--feature-lines", "12.5", "fl.png"], 12.5, ["spot.ply"]),
    (["render", "a.obj", "--feature-lines", "b.ply", "fl.png"], 30.0, ["a.obj", "b.ply"]),
    (["render", "a.obj", "--feature-lines", "example:spot", "fl.png"], 30.0, ["a.obj", "example:spot"]),
    (["render", "a.obj", "--feature-lines", "--edges", "fl.png"], 30.0, ["a.obj"]),
    (["render", "a.obj", "--feature-lines", "-5", "fl.png"], "-5", None),          # a number: told as a bad angle
])
def test_feature_lines_take_only_a_number_or_marked(words, lines, inputs):
    if inputs is None:
        with pytest.raises(ParameterError):
            options_from(operations_parser().parse_args(words))
        return
    args = operations_parser().parse_args(words)
    assert (options_from(args).feature_lines, args.input, args.output) == (lines, inputs, "fl.png")


def test_feature_lines_before_a_png_draws_into_it(tmp_path, capsys):
    from shapeflow import rendering

    if not rendering.available():
        pytest.skip("rendering unavailable (the render extra and offscreen OpenGL)")
    png = tmp_path / "fl.png"
    code, _, err = run_cli(["render", "example:spot_cage", "--feature-lines", png, "--size", "200x150"], capsys)
    assert code == 0, err
    assert png.stat().st_size > 0 and err.startswith("shapeflow render: 1 mesh(es), 200x150 pixels in ")


@pytest.mark.parametrize("words,grid,inputs", [
    (["render", "a.ply", "b.ply", "--grid", "out.png"], "auto", ["a.ply", "b.ply"]),
    (["render", "--grid", "a.ply", "b.ply", "out.png"], "auto", ["a.ply", "b.ply"]),
    (["render", "a.ply", "--grid", "2x1", "b.ply", "out.png"], (2, 1), ["a.ply", "b.ply"]),
    (["render", "a.ply", "b.ply", "out.png", "--grid"], "auto", ["a.ply", "b.ply"]),
])
def test_grid_takes_only_rows_x_columns(words, grid, inputs):
    args = operations_parser().parse_args(words)
    assert (options_from(args).grid, args.input, args.output) == (grid, inputs, "out.png")


def test_the_batch_grammar_reads_them_alike():
    args = operations_parser().parse_args(["render", "--front", "-z", "--feature-lines", "m.ply", "o.png"])
    o = options_from(args)
    assert (o.front, o.feature_lines, args.input, args.output) == ("-z", 30.0, ["m.ply"], "o.png")
