"""``shapeflow info``: descriptions of the test meshes and bundled meshes, clean errors."""

from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import MESHES, ROOT, load_fixture_mesh, requires_shared

import shapeflow as sf
from shapeflow.cli import main


def _info(capsys, *args):
    rc = main(["info", *args])
    out, err = capsys.readouterr()
    return rc, out, err


def _field(out: str, key: str) -> str:
    for line in out.splitlines():
        if line.strip().startswith(key):
            return line.strip()[len(key):].strip()
    raise AssertionError(f"no '{key}' line in:\n{out}")


def suzanne_obj(folder) -> str:
    """Blender's Suzanne primitive (tests/data/blender) as an OBJ file: a head with two eye sockets
    and two separate eyes, 32 triangles and 468 quads."""
    path = str(folder / "suzanne.obj")
    sf.save(path, load_fixture_mesh("suzanne"))
    return path


@requires_shared
@pytest.mark.parametrize("fname,loops,edges", [
    ("rook_cage_hybrid_open.obj", 1, 24),
    ("pawn_cage_quad_open.obj", 1, 24),
    ("suzanne", 4, 13 + 13 + 8 + 8),
    ("plane_holes_tri_open.obj", 27, None),
])
def test_info_open_mesh_boundary_loops(capsys, tmp_path, fname, loops, edges):
    rc, out, err = _info(capsys, suzanne_obj(tmp_path) if fname == "suzanne" else str(MESHES / fname))
    assert rc == 0 and err == ""
    boundary = _field(out, "boundary")
    assert boundary.startswith(f"{loops} loop(s)"), boundary
    if edges is not None:
        assert f", {edges} edges" in boundary
    # OpenSubdiv's 't' creases are kept (written back while the vertex numbering holds): no warning
    warned = [line.strip() for line in out.splitlines() if "warning" in line]
    assert warned == []


@requires_shared
def test_info_open_hybrid_counts(capsys, tmp_path):
    rc, out, _ = _info(capsys, suzanne_obj(tmp_path))
    assert rc == 0
    assert _field(out, "vertices") == "507"
    assert _field(out, "faces") == "500 (32 triangles, 468 quads)"
    assert _field(out, "components") == "3"  # the head and two eyes


@requires_shared
def test_info_closed_mesh(capsys):
    rc, out, err = _info(capsys, str(MESHES / "bob_quad.obj"))
    assert rc == 0 and err == ""
    assert _field(out, "vertices") == "5344"
    assert _field(out, "faces") == "5344 (5344 quads)"
    assert _field(out, "boundary") == "none (closed)"
    assert _field(out, "euler char.") == "0"  # genus 1
    assert _field(out, "manifold") == "yes"
    assert _field(out, "oriented") == "yes"


def test_info_bundled_example(capsys):
    rc, out, err = _info(capsys, "example:spot_cage")
    assert rc == 0 and err == ""
    assert out.splitlines()[0] == "example:spot_cage"
    assert _field(out, "vertices") == "188"
    assert _field(out, "faces") == "180 (4 triangles, 160 quads, 16 5-gons)"
    assert _field(out, "boundary") == "none (closed)"
    assert _field(out, "euler char.") == "2"


def test_info_reports_attributes_of_a_ply(capsys, tmp_path):
    import numpy as np

    import shapeflow as sf
    import shapeflow.io as sio

    m = sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], weights=np.array([0, 0.5, 1]))
    sio.save(tmp_path / "w.ply", m)
    rc, out, _ = _info(capsys, str(tmp_path / "w.ply"))
    assert rc == 0
    assert _field(out, "attributes") == "weight (per vertex)"


def _assert_one_line_error(rc, out, err, *fragments):
    assert rc == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert lines[0].startswith("shapeflow info: error: ")
    for frag in fragments:
        assert frag in lines[0], lines[0]


def test_info_missing_file(capsys, tmp_path):
    path = tmp_path / "missing.obj"
    rc, out, err = _info(capsys, str(path))
    _assert_one_line_error(rc, out, err, str(path), "No such file")


def test_info_garbled_file(capsys, tmp_path):
    path = tmp_path / "garbled.obj"
    path.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 oops\nf 1 2 3\n")
    rc, out, err = _info(capsys, str(path))
    _assert_one_line_error(rc, out, err, str(path), "line 3", "'oops'")


def test_info_binary_junk(capsys, tmp_path):
    path = tmp_path / "junk.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nproperty float x\n"
                     b"property float y\nproperty float z\nend_header\n" + bytes(range(40)))
    rc, out, err = _info(capsys, str(path))
    _assert_one_line_error(rc, out, err, str(path), "vertex 3", "truncated")


def test_info_unknown_example(capsys):
    rc, out, err = _info(capsys, "example:nope")
    _assert_one_line_error(rc, out, err, "nope")


def test_info_warns_about_duplicate_face_and_unreferenced_vertex(capsys, tmp_path):
    path = tmp_path / "suspicious.obj"
    path.write_bytes(
        b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        b"v 7 7 7\n"  # vertex 4: used by no face
        b"f 1 2 3 4\n"
        b"f 2 3 4 1\n"  # the same quad again (rotated)
    )
    rc, out, err = _info(capsys, str(path))
    assert rc == 0 and err == ""
    warnings = [ln.strip() for ln in out.splitlines() if ln.strip().startswith("warning:")]
    assert any("1 unreferenced vertices" in w and "e.g. 4" in w for w in warnings), out
    assert any("1 duplicate faces" in w and "e.g. 1" in w for w in warnings), out


def _run_cli(*args):
    import os

    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-m", "shapeflow.cli", "info", *args],
                          capture_output=True, text=True, timeout=120, env=env)


def test_info_subprocess_no_traceback(tmp_path):
    ok = _run_cli("example:spot_cage")
    assert ok.returncode == 0, ok.stderr
    assert "16 5-gons" in ok.stdout
    bad = tmp_path / "bad.off"
    bad.write_bytes(b"OFF\n3 1 0\n0 0 0\n1 0 0\n")
    res = _run_cli(str(bad))
    assert res.returncode == 2
    assert res.stdout == ""
    assert "Traceback" not in res.stderr
    assert res.stderr.count("\n") == 1 and str(bad) in res.stderr and "line 4" in res.stderr
