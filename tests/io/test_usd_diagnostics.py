"""pxr's diagnostics while shapeflow reads or writes USD: nothing of pxr's on stderr; a composition
cycle (inherits, references, sublayers) is a MeshError naming the prims or layers, any other
report one DataLossWarning; outside shapeflow's calls pxr reports as it always does.  The files are
hand-written USD text; stderr is read at the file-descriptor level (capfd), where pxr prints."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import shapeflow as sf
from shapeflow.errors import DataLossWarning, MeshError

pytest.importorskip("pxr", reason="usd-core (the 'usd' extra) is not installed")
from pxr import Tf  # noqa: E402

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "src")
MESH = ('def Mesh "m" {\n point3f[] points = [(0,0,0),(1,0,0),(0,1,0)]\n int[] faceVertexCounts = [3]\n'
        ' int[] faceVertexIndices = [0,1,2]\n}\n')
CYCLES = {
    "inherits": ('class "c" (inherits = </d>) {}\nclass "d" (inherits = </c>) {}\n',
                 r"In </[cd]>: Cycle detected: </[cd]> inherits from: </[cd]> which CANNOT inherit from: </[cd]>"),
    "references": ('def "a" (references = </b>) {}\ndef "b" (references = </a>) {}\n',
                   r"In </[ab]>: Cycle detected: </[ab]> references: </[ab]> which CANNOT reference: </[ab]>"),
}


def files(tmp_path, main: str, **others) -> str:
    for name, text in others.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "main.usda").write_text(main)
    return str(tmp_path / "main.usda")


@pytest.mark.parametrize("arc", sorted(CYCLES))
def test_an_arc_cycle_is_one_error_and_nothing_on_stderr(tmp_path, capfd, arc):
    text, words = CYCLES[arc]
    path = files(tmp_path, "#usda 1.0\n" + text + MESH)
    with pytest.raises(MeshError, match=rf"^{path}: the USD stage's composition has a cycle \(2 cycles\): {words}$"):
        sf.load(path)
    assert capfd.readouterr().err == ""


def test_a_sublayer_cycle_is_one_error_naming_the_layers(tmp_path, capfd):
    path = files(tmp_path, "#usda 1.0\n(\n subLayers = [@./b.usda@]\n)\n" + MESH,
                 **{"b.usda": "#usda 1.0\n(\n subLayers = [@./main.usda@]\n)\n"})
    with pytest.raises(MeshError, match=r"composition has a cycle: Sublayer hierarchy with root layer @b.usda@ has "
                                        r"cycles. Detected when layer @main.usda@ was seen in the layer stack"):
        sf.load(path)
    assert capfd.readouterr().err == ""


def test_another_report_is_one_warning_and_the_mesh_is_read(tmp_path, capfd):
    lib = MESH.replace('"m"', '"lib"')
    path = files(tmp_path, '#usda 1.0\ndef "a" (references = @./lib.usda@</missing>) {}\n' + MESH,
                 **{"lib.usda": "#usda 1.0\n" + lib})
    said = (r"main.usda: the USD library \(pxr\) reported a problem reading the stage: "
            r"In </a>: Unresolved reference prim path </missing> introduced by </a>$")
    with pytest.warns(DataLossWarning, match=said):
        m = sf.load(path)
    assert m.n_faces == 1
    assert capfd.readouterr().err == ""


def test_pxr_reports_as_before_outside_shapeflows_calls(tmp_path, capfd):
    """The collecting delegate is gone after a read, a failed read and a write: pxr prints again."""
    text, _ = CYCLES["inherits"]
    bad = files(tmp_path, "#usda 1.0\n" + text + MESH)
    with pytest.raises(MeshError):
        sf.load(bad)
    good = tmp_path / "good.usda"
    good.write_text("#usda 1.0\n" + MESH)
    sf.save(tmp_path / "out.usdc", sf.load(good))
    Tf.Warn("a warning of the caller's own")
    err = capfd.readouterr().err
    assert "a warning of the caller's own" in err and "Cycle" not in err


def test_the_cli_answers_a_cycle_in_one_line(tmp_path):
    text, _ = CYCLES["references"]
    files(tmp_path, "#usda 1.0\n" + text + MESH)
    for args in (["info", "main.usda"], ["enhance", "main.usda", "out.usda", "-s", "1"]):
        r = subprocess.run([sys.executable, "-m", "shapeflow", *args], capture_output=True, text=True, cwd=tmp_path,
                           env=dict(os.environ, PYTHONPATH=SRC), timeout=300)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr.startswith(f"shapeflow {args[0]}: error: main.usda: the USD stage's composition has a cycle")
    assert not (tmp_path / "out.usda").exists()
