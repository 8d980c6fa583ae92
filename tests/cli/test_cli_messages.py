"""Usage errors as a user reads them: one line in the user's option names and signs, a "did you mean"
for misspelt commands, options and choices, a hint to --help, never a usage dump; a stroke that
moves nothing says why (and fails with --strict); family --to includes its end on the grid."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.cli import build_parser, main
from shapeflow.errors import ParameterError

#: the one line a command adds on a machine whose numba cache is still empty (a fresh clone)
COMPILING = re.compile(r"shapeflow \w+: compiling the fast kernels \(first run on this machine only; later runs "
                       r"load them from numba's cache\)\n")


def run(capsys, *args):
    """Exit code, stdout and stderr of one command; stderr without the compile notice, which depends
    on what ran before on this machine, not on the command."""
    code = main([str(a) for a in args])
    cap = capsys.readouterr()
    return code, cap.out, COMPILING.sub("", cap.err)


@pytest.mark.parametrize("args,line", [
    (["enhance", "example:spot", "{out}", "--strenght", "5"],
     "shapeflow enhance: error: unrecognized argument --strenght; did you mean --strength? "
     "(see 'shapeflow enhance --help')"),
    (["enhance", "example:spot", "{out}", "-s", "5", "--iteratoins=3"],
     "shapeflow enhance: error: unrecognized argument --iteratoins; did you mean --iterations? "
     "(see 'shapeflow enhance --help')"),
    (["enhanse", "example:spot", "{out}", "-s", "5"],
     "shapeflow: error: unknown command 'enhanse'; did you mean enhance? (see 'shapeflow --help')"),
    (["--verbose", "info", "example:spot"],
     "shapeflow: error: unrecognized argument --verbose; did you mean --version? (see 'shapeflow --help')"),
    (["subdivide", "example:spot", "{out}", "--scheme", "cattmull-clark"],
     "shapeflow subdivide: error: --scheme must be one of catmull-clark, simple, got 'cattmull-clark'; "
     "did you mean catmull-clark? (see 'shapeflow subdivide --help')"),
    (["enhance", "example:spot", "{out}", "--strength", "abc"],
     "shapeflow enhance: error: --strength must be a number, got 'abc' (see 'shapeflow enhance --help')"),
    (["enhance", "example:spot", "{out}", "--strength"],
     "shapeflow enhance: error: --strength needs a value (see 'shapeflow enhance --help')"),
    (["enhance", "example:spot", "{out}"],
     "shapeflow enhance: error: missing --strength (required) (see 'shapeflow enhance --help')"),
    (["enhance", "example:spot", "{out}", "-s", "5", "extra.ply"],
     "shapeflow enhance: error: unexpected argument(s) extra.ply (see 'shapeflow enhance --help')"),
    ([], "shapeflow: error: give a command: batch, brush, curvature, enhance, family, flow, info, render, smooth, "
         "studio, subdivide (see 'shapeflow --help')"),
    # values in the option's own name and sign, checked before they become library parameters
    (["enhance", "example:spot", "{out}", "--strength", "inf"],
     "shapeflow enhance: error: --strength must be finite, got inf"),
    (["enhance", "example:spot", "{out}", "--strength", "-2.5"],
     "shapeflow enhance: error: --strength must be >= 0, got -2.5 (enhance's λ is -strength; to smooth, use "
     "'shapeflow smooth --strength 2.5' or 'shapeflow flow --lambda 2.5')"),
    (["enhance", "example:spot", "{out}", "-s", "-50"],
     "shapeflow enhance: error: --strength must be >= 0, got -50 (enhance's λ is -strength; to smooth, use "
     "'shapeflow smooth --strength 50' or 'shapeflow flow --lambda 50')"),
    (["smooth", "example:spot", "{out}", "-s", "-1e3"],
     "shapeflow smooth: error: --strength must be >= 0, got -1000 (smooth's λ is +strength; to enhance, use "
     "'shapeflow enhance --strength 1000' or 'shapeflow flow --lambda -1000')"),
    (["smooth", "example:spot", "{out}", "--strength", "nan"],
     "shapeflow smooth: error: --strength must be finite, got nan"),
    (["flow", "example:spot", "{out}", "--lambda", "-inf"], "shapeflow flow: error: --lambda must be finite, got -inf"),
    (["enhance", "example:spot", "{out}", "-s", "5", "--lambda-border", "inf"],
     "shapeflow enhance: error: --lambda-border must be finite, got inf"),
    (["enhance", "example:spot", "{out}", "-s", "5", "--iterations", "-1"],
     "shapeflow enhance: error: --iterations must be >= 0, got -1"),
    (["enhance", "example:spot", "{out}", "-s", "5", "--axes", "xw"],
     "shapeflow enhance: error: --axes must be letters from 'xyz', got 'xw'"),
    (["family", "example:spot", "{tmp}/fam", "--to", "-10", "--step", "-5", "--lambda-border", "nan"],
     "shapeflow family: error: --lambda-border must be finite, got nan"),
])
def test_usage_errors_are_one_line(tmp_path, capsys, args, line):
    out = tmp_path / "out.ply"
    code, stdout, err = run(capsys, *[a.format(out=out, tmp=tmp_path) for a in args])
    assert (code, stdout, err) == (2, "", line + "\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_negative_numbers_are_values(tmp_path, capsys):
    out = tmp_path / "o.ply"
    code, _, err = run(capsys, "flow", "example:spot_cage", out, "--lambda", "-1e1", "--lambda-border", "-.5", "-q")
    assert code == 0, err
    m = sf.load_example("spot_cage")
    assert np.array_equal(sf.load(out).vertices, sf.flow(m, -10.0, lam_border=-0.5).vertices)


def test_the_installed_command_says_the_same(tmp_path):
    r = subprocess.run([sys.executable, "-m", "shapeflow", "smooth", "example:spot", str(tmp_path / "o.ply"),
                        "--strenght", "2"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("shapeflow smooth: error: unrecognized argument --strenght; did you mean --strength? "
                        "(see 'shapeflow smooth --help')\n")


def test_help_and_version_exit_zero(capsys):
    assert main(["enhance", "--help"]) == 0
    assert "--strength" in capsys.readouterr().out
    assert main(["--version"]) == 0


def test_the_batch_parser_raises_the_same_message():
    with pytest.raises(ParameterError) as info:
        build_parser(raising=True).parse_args(["enhance", "a.ply", "b.ply", "--strenght", "5"])
    assert str(info.value) == "shapeflow enhance: unrecognized argument --strenght; did you mean --strength?"


# --- a stroke that moves nothing ------------------------------------------------------------

@pytest.mark.parametrize("stroke,why", [
    ({"lambda": -20, "radius": 0.05, "points": [[5, 5, 5]]},
     'no vertex lies within "radius" 0.05 of its 1 dab(s) (the nearest is {d:.4g} away; the mesh\'s '
     "bounding-box diagonal is {diag:.4g})"),
    ({"lambda": 0, "radius": 0.3, "points": [[0.0, 0.3, -0.6]]}, '"lambda" is 0'),
])
def test_a_stroke_that_moves_nothing_says_why(tmp_path, capsys, stroke, why):
    spot = sf.load_example("spot")
    d = float(np.linalg.norm(spot.vertices - [5, 5, 5], axis=1).min())
    why = why.format(d=d, diag=spot.diagonal)
    (tmp_path / "s.json").write_text(json.dumps(stroke))
    out = tmp_path / "out.ply"
    code, _, err = run(capsys, "brush", "example:spot", out, "--stroke", tmp_path / "s.json", "-q")
    assert code == 0
    assert err == f"shapeflow brush: warning: the stroke moved no vertex: {why}; the output is the input\n"
    assert np.array_equal(sf.load(out).vertices, spot.vertices)
    out.unlink()
    code, _, err = run(capsys, "brush", "example:spot", out, "--stroke", tmp_path / "s.json", "--strict")
    assert code == 2 and err == f"shapeflow brush: error: the stroke moved no vertex: {why} (--strict)\n"
    assert not out.exists()


def test_a_stroke_that_moves_something_does_not_warn(tmp_path, capsys):
    spot = sf.load_example("spot")
    (tmp_path / "s.json").write_text(json.dumps({"lambda": -20, "radius": 0.3, "points": [spot.vertices[0].tolist()]}))
    code, _, err = run(capsys, "brush", "example:spot", tmp_path / "o.ply", "--stroke", tmp_path / "s.json", "--strict")
    assert code == 0 and "warning" not in err and " 0 of " not in err


def test_the_brush_warm_up_runs():
    from shapeflow.commands.brush import warm_up_brush

    assert warm_up_brush() >= 0.0


# --- family --to ------------------------------------------------------------------------------

def _lams(**kw):
    from shapeflow.commands.family import member_lambdas

    base = dict(lambdas=None, lam_from=None, lam_to=None, lam_step=None)
    return member_lambdas(SimpleNamespace(**{**base, **kw}))


def test_family_to_includes_its_end_on_the_grid():
    lams = _lams(lam_from=0.0, lam_to=-240.0, lam_step=-5.0)
    assert len(lams) == 49 and lams[0] == 0.0 and lams[-1] == -240.0
    assert lams == [-5.0 * i + 0.0 for i in range(49)]
    assert _lams(lam_to=-7.0, lam_step=-5.0) == [0.0, -5.0]                  # off the grid: up to it
    assert _lams(lam_from=0.1, lam_to=0.7, lam_step=0.2) == [0.1, 0.3, 0.5, 0.7]
    assert _lams(lam_from=3.0, lam_to=3.0, lam_step=1.0) == [3.0]
    with pytest.raises(ParameterError, match="towards --to"):
        _lams(lam_to=10.0, lam_step=-5.0)


def test_family_command_writes_the_end_member(tmp_path, capsys):
    code, _, err = run(capsys, "family", "example:spot_cage", tmp_path / "f", "--to", "-10", "--step", "-5", "-q")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == [
        "spot_cage_0_lam+000.0.ply", "spot_cage_1_lam-005.0.ply", "spot_cage_2_lam-010.0.ply"]
