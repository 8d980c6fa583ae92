"""USD write-back of a layer that composes itself, crate files written beside the output (never in
the system's temporary folder), and pxr's failures while writing told in one line naming the output.
Files are built here as text or with pxr; what is written is read back with pxr."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile

import numpy as np
import pytest

import shapeflow as sf

pytest.importorskip("pxr", reason="usd-core (the 'usd' extra) is not installed")
from pxr import Sdf, Usd  # noqa: E402

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "src")
POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]])
SELF_REF = """#usda 1.0
def "a" (references = @./self.usda@</m>) {}
def Mesh "m" {
 point3f[] points = [(0,0,0),(1,0,0),(0,1,0),(1,1,0.5)]
 int[] faceVertexCounts = [3, 3]
 int[] faceVertexIndices = [0,1,2, 1,3,2]
}
"""


def points_of(path, prim):
    stage = Usd.Stage.Open(str(path))
    return np.asarray(stage.GetPrimAtPath(prim).GetAttribute("points").Get(), np.float64)


@pytest.fixture
def self_ref(tmp_path):
    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    src = tmp_path / "in" / "self.usda"
    src.write_text(SELF_REF)
    return src


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_a_layer_that_references_itself_is_written_back_flattened(self_ref, tmp_path, ext):
    """The reference is composed on reading (prim /a is /m's copy); the written file holds both
    prims with their new points and refers to no file (its text alone, elsewhere, would not find
    /m through @./self.usda@)."""
    m = sf.load(self_ref)
    assert m.n_vertices == 8 and np.array_equal(m.vertices, np.concatenate([POINTS, POINTS]))
    moved = m.with_vertices(m.vertices * 2 + [0.5, 0, 0])
    out = tmp_path / "out" / f"o{ext}"
    sf.save(out, moved)
    for prim in ("/a", "/m"):
        np.testing.assert_allclose(points_of(out, prim), POINTS * 2 + [0.5, 0, 0], rtol=1e-7)
    assert not Sdf.Layer.FindOrOpen(str(out)).GetCompositionAssetDependencies()
    assert sorted(os.listdir(out.parent)) == [out.name]


@pytest.fixture
def no_temporary_folder(tmp_path, monkeypatch):
    """The system's temporary folder unusable: TMPDIR names a folder that does not exist."""
    missing = str(tmp_path / "no such folder")
    monkeypatch.setenv("TMPDIR", missing)
    monkeypatch.setattr(tempfile, "tempdir", missing)
    return missing


def test_a_crate_is_written_beside_its_output(self_ref, tmp_path, no_temporary_folder):
    m = sf.load(self_ref)
    out = tmp_path / "out" / "o.usdc"
    sf.save(out, m.with_vertices(m.vertices * 3))
    assert out.read_bytes()[:8] == b"PXR-USDC"
    np.testing.assert_allclose(points_of(out, "/m"), POINTS * 3, rtol=1e-7)
    assert sorted(os.listdir(out.parent)) == ["o.usdc"]          # the crate's own file is gone
    assert not os.path.exists(no_temporary_folder)


def test_pxr_failing_to_write_is_one_error_naming_the_output(self_ref, tmp_path, monkeypatch):
    """pxr cannot create the crate (its folder is a file): a MeshError naming the output, in one
    line, and no output file."""
    import shapeflow.io.usd as usd

    blocker = tmp_path / "a file"
    blocker.write_text("")

    @contextlib.contextmanager
    def unwritable(suffix):
        yield str(blocker / f"x{suffix}")

    monkeypatch.setattr(usd, "side_file", unwritable)
    out = tmp_path / "out" / "o.usdc"
    with pytest.raises(sf.MeshError) as info:
        sf.save(out, sf.load(self_ref))
    text = str(info.value)
    assert text.startswith(f"{out}: the USD library (pxr) cannot write the stage (ErrorException: ")
    assert "\n" not in text and not out.exists()


#: the CLI with the system's temporary folder unusable (a folder that does not exist), as a full one is
CLI_WITHOUT_TMP = ("import sys, tempfile; tempfile.tempdir = sys.argv.pop(1); "
                   "from shapeflow.cli import main; sys.exit(main(sys.argv[1:]))")


def test_the_cli_writes_both_back_in_one_line(self_ref, tmp_path):
    """Run from another folder than the file's (pxr would otherwise find @./self.usda@ from the
    working folder), with no usable temporary folder."""
    missing = str(tmp_path / "no such folder")
    for out in ("out/o.usda", "out/o.usdc"):
        r = subprocess.run([sys.executable, "-c", CLI_WITHOUT_TMP, missing, "enhance", "in/self.usda", out, "-s", "1"],
                           capture_output=True, text=True, cwd=tmp_path, env=dict(os.environ, PYTHONPATH=SRC),
                           timeout=300)
        assert r.returncode == 0, r.stderr
        assert "error" not in r.stderr and not any(line.startswith(("Warning", "Error", "Coding"))
                                                   for line in r.stderr.splitlines()), r.stderr
        assert r.stderr.splitlines()[-1].endswith(f"-> {out}")
    assert sorted(os.listdir(tmp_path / "out")) == ["o.usda", "o.usdc"] and not os.path.exists(missing)
