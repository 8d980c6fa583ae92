"""The command layer from Python: options that check their values in the options' names, a command run
with a reporter of one's own, the same result as the library."""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow import commands
from shapeflow.commands import (
    Collector,
    FamilyOptions,
    FlowOptions,
    RenderOptions,
    Reporter,
    SubdivideOptions,
)
from shapeflow.errors import ParameterError


@pytest.mark.parametrize("make, message", [
    (lambda: FlowOptions(command="enhance", strength=float("inf")), "--strength must be finite, got inf"),
    (lambda: FlowOptions(command="smooth", strength=-2.5), "--strength must be >= 0, got -2.5"),
    (lambda: FlowOptions(lam=-1.0, iterations=-1), "--iterations must be >= 0, got -1"),
    (lambda: FlowOptions(lam=-1.0, axes="xw"), "--axes must be letters from 'xyz', got 'xw'"),
    (lambda: FlowOptions(lam=-1.0, lambda_border=float("nan")), "--lambda-border must be finite, got nan"),
    (lambda: FlowOptions(command="sharpen", strength=1.0), "command must be flow, enhance or smooth"),
    (lambda: FamilyOptions(lam_to=10.0, lam_step=-5.0), "--from 0 --to 10 --step -5 gives no λ"),
    (lambda: FamilyOptions(lambdas="1,2", name="a/b"), "--name must be a plain file name prefix"),
    (lambda: SubdivideOptions(levels=-1), "--levels must be >= 0; got -1"),
    (lambda: RenderOptions(clim="low"), "--range must be LO,HI; got 'low'"),
    (lambda: RenderOptions(color="displacement"), "--color displacement needs a reference"),
])
def test_options_check_their_values_in_the_option_names(make, message):
    with pytest.raises(ParameterError) as info:
        make()
    assert str(info.value).startswith(message)


def test_options_hold_their_values_parsed():
    assert FlowOptions(command="enhance", strength=3.0).signed_lambda == -3.0
    assert FlowOptions(command="smooth", strength=3.0).signed_lambda == 3.0
    assert FamilyOptions(lam_to=-10.0, lam_step=-5.0).lams == (0.0, -5.0, -10.0)
    r = RenderOptions(size="80x60", grid="2x3", clim="-1,1", labels=["a", "b"])
    assert (r.size, r.grid, r.clim, r.labels) == ((80, 60), (2, 3), (-1.0, 1.0), ("a", "b"))


class Kinds(Reporter):
    """A reporter that keeps which kind of line each was."""

    def __init__(self):
        self.said = []

    def message(self, text):
        self.said.append(("message", text))

    def warning(self, text):
        self.said.append(("warning", text))


def test_a_command_from_python_gives_the_librarys_result(tmp_path):
    out = tmp_path / "out.ply"
    said = Collector()
    commands.run(FlowOptions(command="enhance", strength=20.0), "example:spot", str(out), said)
    spot = sf.load_example("spot")
    np.testing.assert_array_equal(sf.load(out).vertices, sf.enhance(spot, 20.0).vertices)
    assert len(said.messages) == 1 and said.messages[0].startswith("shapeflow enhance: λ=-20, 1 iteration(s), ")
    assert said.messages[0].endswith(f"-> {out}")
    assert said.facts["vertices"] == spot.n_vertices and said.facts["report"].lam == -20.0


def test_warnings_are_told_as_warnings(tmp_path):
    said = Kinds()
    commands.run(FlowOptions(command="smooth", strength=1e6), "example:spot", str(tmp_path / "o.ply"), said)
    assert [kind for kind, _ in said.said] == ["warning", "message"]
    assert "collapsed the model" in said.said[0][1]


def test_a_silent_run_and_a_wrong_options_object(tmp_path):
    commands.run(SubdivideOptions(levels=1), "example:spot_cage", str(tmp_path / "s.obj"))     # nobody hears it
    cage = sf.load_example("spot_cage")
    assert sf.load(tmp_path / "s.obj").n_vertices == sf.subdivide(cage, 1).n_vertices
    with pytest.raises(ParameterError, match="options must be those of an operation"):
        commands.run(object(), "example:spot", str(tmp_path / "x.ply"))


@pytest.mark.parametrize("scale", [1e-200, 1e200])
@pytest.mark.parametrize("command, strength", [("smooth", 1e6), ("enhance", 1e6)])
def test_the_strong_lambda_warnings_hold_at_any_scale(tmp_path, scale, command, strength):
    """The same words and figures as at the model's own scale (the squares of 1e200 overflowed)."""
    spot = sf.load_example("spot")
    sf.save(tmp_path / "big.ply", spot.with_vertices(spot.vertices * scale))
    told = []
    for src in ("example:spot", str(tmp_path / "big.ply")):
        said = Kinds()
        commands.run(FlowOptions(command=command, strength=strength), src, str(tmp_path / f"o{len(told)}.ply"), said)
        told.append([text.split(": ", 1)[1] for kind, text in said.said if kind == "warning"])
    assert told[0] and told[0] == told[1]
