"""Hostile and ambiguous files: declared sizes never trusted, ambiguity is an error, valid files accepted."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import shapeflow as sf
from shapeflow import io as sio
from shapeflow.errors import MeshError

TRI_V = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]


def binary_ply(n_vertex_decl=3, n_face_decl=1, comment="", faces=((0, 1, 2),), extra_header=""):
    head = (f"ply\nformat binary_little_endian 1.0\n{comment}element vertex {n_vertex_decl}\n"
            f"property float x\nproperty float y\nproperty float z\n{extra_header}"
            f"element face {n_face_decl}\nproperty list uchar int vertex_indices\nend_header\n").encode("utf-8")
    body = b"".join(struct.pack("<3f", *v) for v in TRI_V)
    body += b"".join(struct.pack("<B3i", 3, *f) for f in faces)
    return head + body


# --- declared counts: the reader must not allocate from them --------------------------------------

LIMITED = textwrap.dedent("""
    import resource, sys
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))   # 1 GiB of address space
    import shapeflow.io as sio
    from shapeflow.errors import MeshError
    try:
        sio.load(sys.argv[1]) if sys.argv[1].endswith(("ply", "obj", "off")) else sio.load_weights(sys.argv[1], 3)
    except MeshError as exc:
        print("MeshError:", exc)
    except BaseException as exc:
        print("OTHER:", type(exc).__name__, exc)
""")


def _npy(shape_text: str) -> bytes:
    header = f"{{'descr': '<f8', 'fortran_order': False, 'shape': {shape_text}, }}"
    header = header.ljust(117) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + struct.pack("<3d", 0, 0.5, 1)


@pytest.mark.parametrize("name,data", [
    ("faces3e8.ply", binary_ply(n_face_decl=300_000_000)),
    ("faces1e12.ply", binary_ply(n_face_decl=10 ** 12)),
    ("verts1e12.ply", binary_ply(n_vertex_decl=10 ** 12)),
    ("faces1e30.ply", binary_ply(n_face_decl=10 ** 30)),
    ("ascii1e12.ply", b"ply\nformat ascii 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
                      b"property float z\nend_header\n0 0 0\n"),
    ("off1e12.off", b"OFF\n1000000000000 1000000000000 0\n0 0 0\n"),
    ("w1e12.npy", _npy("(1000000000000,)")),
    ("w3e8.npy", _npy("(300000000,)")),
], ids=lambda v: v if isinstance(v, str) else "")
def test_declared_sizes_are_not_trusted(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data)
    r = subprocess.run([sys.executable, "-c", LIMITED, str(path)], capture_output=True, text=True, timeout=120)
    assert r.stdout.startswith("MeshError:"), (r.stdout, r.stderr[-2000:])
    assert name in r.stdout


# --- ambiguity is an error naming the line or element ------------------------------------------------

@pytest.mark.parametrize("text,match", ids=["f1", "vt0.5", "v0"], argvalues=[
    (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf1 2 3\n", r"line 4: .*'f1'.*space missing"),
    (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nvt0.5 0.5\n", r"line 5: .*'vt0.5'"),
    (b"v0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 2 3 4\n", r"line 1: .*'v0'"),
])
def test_obj_glued_tags_are_errors(tmp_path, text, match):
    p = tmp_path / "m.obj"
    p.write_bytes(text)
    with pytest.raises(MeshError, match=match):
        sio.load(p)


def test_obj_other_tags_still_read(tmp_path):
    p = tmp_path / "m.obj"
    p.write_bytes(b"mtllib a.mtl\no thing\ng grp\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nusemtl m-1.x\n"
                  b"s off\nf 1/1/1 2/1/1 3/1/1\nl 1 2\ncurv 0 1 1 2\nl -1 -2\n")
    with pytest.warns(sf.DataLossWarning, match="1 'curv' line, 1 'l \\(relative indices\\)' line"):
        m = sio.load(p)
    assert m.metadata["obj"]["elements"] == [("l", "1 2")]      # kept: written back after the faces
    assert np.array_equal(m.vertices, TRI_V) and m.faces_as_lists() == [[0, 1, 2]]
    assert m.corner_attributes["uv"].index.tolist() == [0, 0, 0]
    assert m.face_attributes["material"].values().tolist() == ["m-1.x"]
    assert m.metadata["obj"]["mtllib"] == ["a.mtl"]


ASCII_HEAD = "ply\nformat ascii 1.0\n{}end_header\n"


@pytest.mark.parametrize("header,body,match", ids=["two-x", "two-vertex", "two-face", "non-ascii"], argvalues=[
    ("element vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float x\n"
     "element face 1\nproperty list uchar int vertex_indices\n", "0 0 0 5\n1 0 0 5\n0 1 0 5\n3 0 1 2\n",
     r"line 7: property 'x' of element 'vertex' is declared twice"),
    ("element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
     "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
     "element face 1\nproperty list uchar int vertex_indices\n", "0 0 0\n1 0 0\n0 1 0\n9 9 9\n3 0 1 2\n",
     r"line 7: a second 'vertex' element \(the first is on line 3\)"),
    ("element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
     "element face 1\nproperty list uchar int vertex_indices\nelement face 1\nproperty list uchar int vertex_indices\n",
     "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2 1\n", r"a second 'face' element"),
    ("element vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float é\n",
     "0 0 0 1\n1 0 0 1\n0 1 0 1\n", r"line 7: non-ASCII"),
])
def test_ply_ambiguity_is_an_error(tmp_path, header, body, match):
    p = tmp_path / "m.ply"
    p.write_bytes((ASCII_HEAD.format(header) + body).encode("utf-8"))
    with pytest.raises(MeshError, match=match):
        sio.load(p)


MANY_PROPERTIES = textwrap.dedent("""
    import sys
    import shapeflow.io as sio
    from shapeflow.errors import MeshError
    m = sio.load(sys.argv[1])
    print(m.n_vertices, m.n_faces, len(m.attributes), m.attributes["p0"].tolist(), m.attributes["p199999"].tolist())
    try:
        sio.load(sys.argv[2])
    except MeshError as exc:
        print(exc)
""")


def test_a_ply_header_of_200000_properties_is_read_in_one_pass(tmp_path):
    """Duplicate names are looked up in a set: 200,000 property lines, which took more than 16 minutes
    when each was compared with the ones before it.  A hang detector (the subprocess's timeout), not a
    clock, bounds the run."""
    n = 200_000
    props = "".join(f"property uchar p{i}\n" for i in range(n))
    head = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            + props + "{}element face 1\nproperty list uchar int vertex_indices\nend_header\n")
    rows = [f"{v} " + " ".join(str((i + k) % 256) for i in range(n)) for k, v in enumerate(("0 0 0", "1 0 0", "0 1 0"))]
    body = "\n".join(rows) + "\n3 0 1 2\n"
    (tmp_path / "many.ply").write_text(head.format("") + body)
    (tmp_path / "twice.ply").write_text(head.format("property uchar p0\n") + body)
    script = tmp_path / "run.py"
    script.write_text(MANY_PROPERTIES)
    out = subprocess.run([sys.executable, str(script), str(tmp_path / "many.ply"), str(tmp_path / "twice.ply")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == f"3 1 {n} [0, 1, 2] [{(n - 1) % 256}, {n % 256}, {(n + 1) % 256}]"
    assert lines[1].endswith(f"line {n + 7}: property 'p0' of element 'vertex' is declared twice; "
                             "which one holds the values is ambiguous")


def test_a_ply_header_is_at_most_16_mib(tmp_path):
    comments = b"comment " + b"x" * 1000 + b"\n"
    filler = comments * (17 * 1024)                       # 17 MiB of comment lines
    for tail in (b"", b"element vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n"):
        p = tmp_path / "long.ply"
        p.write_bytes(b"ply\nformat ascii 1.0\n" + filler + tail)
        with pytest.raises(MeshError, match=r"long.ply: no 'end_header' line in the first 16 MiB: a PLY header is "
                                            r"at most 16 MiB \(about 700,000 property lines\)"):
            sio.load(p)
    p.write_bytes(b"ply\nformat ascii 1.0\n" + comments * (15 * 1024) + tail)     # 15 MiB: read
    assert sio.load(p).n_vertices == 0


# --- valid files that used to be refused -----------------------------------------------------------

@pytest.mark.parametrize("bom", [b"", b"\xef\xbb\xbf"], ids=["no-bom", "bom"])
@pytest.mark.parametrize("comment", ["", "comment Überarbeitet von José, 東京\n", "obj_info scanné 2026\n"],
                         ids=["plain", "utf8-comment", "utf8-obj_info"])
@pytest.mark.parametrize("kind", ["ascii", "binary"])
def test_ply_with_utf8_comments_and_bom(tmp_path, bom, comment, kind):
    if kind == "binary":
        data = binary_ply(comment=comment)
    else:
        data = (f"ply\nformat ascii 1.0\n{comment}element vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").encode("utf-8")
    p = tmp_path / "m.ply"
    p.write_bytes(bom + data)
    assert sio.load(p) == sf.Mesh(TRI_V, [[0, 1, 2]])


def test_devices_and_pipes_are_not_read(tmp_path):
    link = tmp_path / "zero.ply"
    link.symlink_to("/dev/zero")        # endless: reading it would never finish
    with pytest.raises(MeshError, match="not a regular file"):
        sio.load(link)
    fifo = tmp_path / "pipe.obj"
    os.mkfifo(fifo)
    with pytest.raises(MeshError, match="not a regular file"):
        sio.load(fifo)
