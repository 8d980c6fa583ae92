"""OBJ polylines ``l``, points ``p`` and OpenSubdiv tags ``t``: checked as faces are (a MeshError
naming the line), never written back invalid; material libraries named by ``mtllib`` that are not
beside a file written elsewhere are named in a DataLossWarning."""

from __future__ import annotations

import os
import warnings

import pytest

import shapeflow as sf
from shapeflow.errors import DataLossWarning, MeshError

HEAD = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nf 1 2 3\nf 2 4 3\n"     # lines 1-8


@pytest.mark.parametrize("line, match", [
    ("l 1 99999999999", r"vertex index 99999999999 out of range: the file has 4 vertices"),
    ("l 1 5", r"vertex index 5 out of range: the file has 4 vertices"),
    ("l 1 0", r"vertex index 0 \(OBJ indices start at 1\)"),
    ("l 2", r"a polyline \('l'\) needs at least 2 vertices, this one has 1"),
    ("p", r"a 'p' line needs at least 1 vertex, this one has 0"),
    ("p 1 7", r"vertex index 7 out of range"),
    ("p 1.5", r"'1.5' is not a valid vertex index"),
    ("p 1/1", r"'1/1' is not a corner of the form v"),
    ("l 1/1 2/3", r"texture coordinate index 3 out of range: the file has 2 texture coordinates"),
    ("l 1/0 2/1", r"texture coordinate index 0"),
    ("l 1 2/", r"'2/' is not a corner of the form v or v/vt"),
    ("l 1 2/1/1", r"'2/1/1' is not a corner of the form v or v/vt"),
    ("l 1 x", r"'x' is not a valid vertex index"),
    ("t crease 999999999/1/1", r"'t crease 999999999/1/1' declares 1000000001 values; the line has 0"),
    ("t crease 2/1/0 0 4 1.0", r"'t crease': vertex 4 out of range: the file has 4 vertices, numbered from 0"),
    ("t crease 2/1/0 -1 0 1.0", r"'t crease': vertex -1 out of range"),
    ("t corner 1/1/0 9 1.0", r"'t corner': vertex 9 out of range"),
    ("t hole 1/0/0 2", r"'t hole': face 2 out of range: the file has 2 faces"),
    ("t crease 2/1/0 0 1.5 1.0", r"'t crease': its 2 integers are not all integers"),
    ("t crease 2/1/0 0 1 sharp", r"'t crease': its 1 floats are not all numbers"),
    ("t crease 2 0 1 1.0", r"'t crease': '2' is not the counts ints/floats\[/strings\]"),
    ("t", r"a 't' line needs a tag name and its counts"),
])
def test_hostile_element_lines_are_refused_by_line(tmp_path, line, match):
    p = tmp_path / "m.obj"
    p.write_text(HEAD + line + "\n")
    with pytest.raises(MeshError, match=f"^{p}: line 9: {match}"):
        sf.load(p)


def test_valid_element_lines_are_kept_and_written_back(tmp_path):
    lines = ["l 1 2 4", "l 1/1 2/2", "p 3", "p 1 2 3 4", "t crease 2/1/0 1 2 10", "t corner 1/1/0 3 2.5",
             "t hole 1/0/0 1", "t interpolateboundary 1/0/0 -1", "t creasemethod 0/0/1 chaikin"]
    p, out = tmp_path / "m.obj", tmp_path / "o.obj"
    p.write_text(HEAD + "\n".join(lines) + "\nl -1 -2\n")
    with pytest.warns(DataLossWarning, match=r"1 'l \(relative indices\)' line"):
        m = sf.load(p)
    assert m.metadata["obj"]["elements"] == [tuple(x.split(" ", 1)) for x in lines]
    sf.save(out, m.with_vertices(m.vertices * 2))
    written = out.read_text().splitlines()
    assert written[-len(lines):] == lines
    assert sf.load(out).metadata["obj"]["elements"] == m.metadata["obj"]["elements"]


@pytest.fixture
def with_library(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "m.mtl").write_text("newmtl red\nKd 1 0 0\nmap_Kd red.png\n")
    (src / "m.obj").write_text("mtllib m.mtl\n" + HEAD.replace("f 1 2 3", "usemtl red\nf 1 2 3"))
    return src / "m.obj"


def test_a_library_not_beside_the_output_is_named(with_library, tmp_path):
    m = sf.load(with_library)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    with pytest.warns(DataLossWarning, match=r"the material library 'm.mtl' named by 'mtllib' is not in the output's "
                                             rf"folder: materials will not show until it is copied there from "
                                             rf"{with_library.parent}"):
        sf.save(out_dir / "o.obj", m)
    assert "mtllib m.mtl" in (out_dir / "o.obj").read_text() and os.listdir(out_dir) == ["o.obj"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataLossWarning)
        sf.save(with_library.parent / "beside.obj", m)              # its folder holds m.mtl
        (out_dir / "m.mtl").write_text("newmtl red\n")
        sf.save(out_dir / "o2.obj", m)                             # the output's folder has one now


def test_a_library_of_a_mesh_from_elsewhere_is_named_too(tmp_path):
    m = sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], metadata={"obj": {"mtllib": ["a.mtl b.mtl"]}})
    with pytest.warns(DataLossWarning, match=r"libraries 'a.mtl', 'b.mtl' named by 'mtllib' are not in the output's "
                                             r"folder: materials will not show \(shapeflow writes the OBJ file only\)"):
        sf.save(tmp_path / "o.obj", m)


def test_a_library_the_source_lacks_too_is_not_named(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    (src / "m.obj").write_text("mtllib absent.mtl\n" + HEAD)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataLossWarning)
        sf.save(out / "o.obj", sf.load(src / "m.obj"))              # nothing lost that the source had
