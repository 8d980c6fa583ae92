"""The command line never prints a traceback: bad input is one line and exit 2, a bug one line and exit 70."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import run_cli


@pytest.mark.parametrize("args,match", [
    (["smooth", "example:spot", "{out}", "--strength", "1e16"], "error: --strength must be <= 1e+12 "),
    (["enhance", "example:spot", "{out}", "--strength", "1e300"], "error: --strength must be <= 1e+12 "),
    (["flow", "example:spot", "{out}", "--lambda", "1", "--lambda-border=-1e20"],
     "error: |--lambda-border| must be <= 1e+12 "),
    (["family", "example:spot", "{tmp}/fam", "--from", "0", "--to=-2e13", "--step=-1e13"], "<= 1e+12"),
    (["flow", "example:spot", "{out}", "--lambda", "1", "--iterations", "1000000000"],
     "error: --iterations must be <= 100000, got 1000000000"),
    (["studio", "example:spot", "--max-upload", "0", "--no-browser"], "--max-upload"),
])
def test_huge_parameters_are_one_line(tmp_path, capsys, args, match):
    out = tmp_path / "out.ply"
    code, _, err = run_cli([a.format(out=out, tmp=tmp_path) for a in args], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and match in err, err
    assert not out.exists()


def test_unexpected_error_is_one_line_and_debug_shows_it(tmp_path, capsys, monkeypatch):
    flow_mod = sys.modules["shapeflow.flow"]

    def boom(*a, **k):
        raise RuntimeError("kaboom\nsecond line")

    monkeypatch.setattr(flow_mod.FlowSolver, "run", boom)
    out = tmp_path / "o.ply"
    code, _, err = run_cli(["smooth", "example:spot", out, "--strength", "1"], capsys)
    assert code == 70
    assert err.strip() == ("shapeflow smooth: internal error: RuntimeError: kaboom (rerun with --debug for the "
                           "traceback, and please report it)")
    assert not out.exists()
    for args in (["--debug", "smooth", "example:spot", out, "--strength", "1"],
                 ["smooth", "example:spot", out, "--strength", "1", "--debug"]):
        with pytest.raises(RuntimeError, match="kaboom"):
            run_cli(args, capsys)


def test_subprocess_huge_lambda_has_no_traceback(tmp_path):
    r = subprocess.run([sys.executable, "-m", "shapeflow", "smooth", "example:spot", str(tmp_path / "o.ply"),
                        "--strength", "1e16"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []
