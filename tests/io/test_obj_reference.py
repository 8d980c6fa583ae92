"""The OBJ reader against a slow line-by-line reader written here, on generated files that mix
every corner form (v, v/t, v//n, v/t/n, v/ and v/t/), relative indices, v/vt/vn/f lines
interleaved, groups and materials, comments (whole lines and after data), blank lines, tabs,
CRLF and continued lines: positions bit for bit (Python's float() rounds correctly), faces in
order, uv and normal tables and indices, group and material per face, comments.  And hostile
corners put into one face line of such a file: the MeshError names that line."""

from __future__ import annotations

import re

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.errors import MeshError

FORMS = ("{v}", "{v}/{t}", "{v}//{n}", "{v}/{t}/{n}", "{v}/", "{v}/{t}/")
NUMBER = ("{!r}", "{:.6f}", "{:.3e}", "{:.0f}", "{:+.4f}")


def _generate(seed: int, n_lines: int, crlf: bool = False) -> bytes:
    """An OBJ text of about ``n_lines`` lines whose kinds come in random order (each face refers only
    to lines before it)."""
    rng = np.random.default_rng(seed)
    out = ["# generated", "mtllib a.mtl b.mtl"]
    nv = nt = nn = 0

    def num():
        x = float(rng.normal() * 10.0 ** rng.integers(-3, 4))
        return NUMBER[rng.integers(len(NUMBER))].format(x)

    def index(count):          # absolute (from 1) or relative (negative)
        i = int(rng.integers(count))
        return str(i + 1) if rng.random() < 0.8 else str(i - count)

    for _ in range(n_lines):
        r = rng.random()
        if r < 0.3 or nv < 6:
            nv += 1
            out.append("v " + " ".join(num() for _ in range(3)) + (" # vertex" if rng.random() < 0.05 else ""))
        elif r < 0.4:
            nt += 1
            out.append("vt " + " ".join(num() for _ in range(2)))
        elif r < 0.5:
            nn += 1
            out.append("vn\t" + " ".join(num() for _ in range(3)))
        elif r < 0.53:
            out.append(f"g part{rng.integers(5)}" + (" side" if rng.random() < 0.5 else ""))
        elif r < 0.55:
            out.append(f"usemtl m{rng.integers(3)}")
        elif r < 0.57:
            out.append(rng.choice(["", "   ", "# a comment line", "  # indented comment"]))
        else:
            k = int(rng.integers(3, 7))
            corners = rng.choice(nv, size=k, replace=False) + 1
            words = []
            for c in corners.tolist():
                form = FORMS[rng.integers(len(FORMS))] if nt and nn else "{v}"
                v = str(c) if rng.random() < 0.8 else str(c - 1 - nv)
                words.append(form.format(v=v, t=index(max(nt, 1)), n=index(max(nn, 1))))
            sep = " \\\n  " if rng.random() < 0.03 else " "       # a continued line
            out.append("f " + " ".join(words[:2]) + sep + " ".join(words[2:]))
    text = "\n".join(out) + "\n"
    return (text.replace("\n", "\r\n") if crlf else text).encode()


def _reference(data: bytes):
    """Read the OBJ text line by line: positions, faces, uv/normal tables and per-corner indices
    (-1: none), group and material of each face, comments."""
    text = data.decode().replace("\r\n", "\n")
    comments = [m.group(1).rstrip() for m in re.finditer(r"^[ \t]*#[ \t]?([^\n]*)", text, re.M)]
    text = re.sub(r"#[^\n]*", "", text)
    text = re.sub(r"\\[ \t]*\n", " ", text)
    tables = {"v": [], "vt": [], "vn": []}
    faces, tex, nrm, groups, mats, state = [], [], [], [], [], {"g": "", "usemtl": ""}
    for line in text.split("\n"):
        words = line.split()
        if not words:
            continue
        tag, rest = words[0], words[1:]
        if tag in tables:
            tables[tag].append([float(x) for x in rest])
        elif tag in state:
            state[tag] = " ".join(rest)
        elif tag == "f":
            for w in rest:
                parts = (w.split("/") + ["", ""])[:3]
                for part, table, out in zip(parts, ("v", "vt", "vn"), (faces, tex, nrm)):
                    i = int(part) if part else None
                    count = len(tables[table])
                    out.append(-1 if i is None else (i - 1 if i > 0 else count + i))
            groups.append(state["g"])
            mats.append(state["usemtl"])
        elif tag != "mtllib":
            raise AssertionError(f"the generator wrote {tag!r}")
    return tables, faces, tex, nrm, groups, mats, comments


@pytest.mark.parametrize("seed, n_lines, crlf", [(0, 40, False), (1, 400, True), (2, 6000, False),
                                                 (3, 30000, False)])
def test_the_reader_agrees_with_a_line_by_line_reader(tmp_path, seed, n_lines, crlf):
    data = _generate(seed, n_lines, crlf)
    path = tmp_path / "g.obj"
    path.write_bytes(data)
    m = sf.load(path)
    tables, faces, tex, nrm, groups, mats, comments = _reference(data)
    v = np.array(tables["v"])
    assert m.vertices.tobytes() == v.tobytes()                       # bit for bit
    assert m.face_indices.tolist() == faces
    assert m.face_sizes.sum() == len(faces)
    uv, normal = m.corner_attributes["uv"], m.corner_attributes["normal"]
    assert uv.values.tobytes() == np.array(tables["vt"]).tobytes()
    assert normal.values.tobytes() == np.array(tables["vn"]).tobytes()
    assert uv.index.tolist() == tex and normal.index.tolist() == nrm
    assert min(tex) == -1 < max(tex) and min(nrm) == -1 < max(nrm)   # the file has both kinds of corner
    assert m.face_attributes["group"].values().tolist() == groups
    assert m.face_attributes["material"].values().tolist() == mats
    assert m.metadata["obj"]["comments"] == comments
    assert m.metadata["obj"]["mtllib"] == ["a.mtl b.mtl"]


HOSTILE = {"1/2/3/4": "is not a valid normal index", "/1/1": "has no vertex index",
           "1.5/1/1": "is not a valid vertex index", "1/x/1": "is not a valid texture coordinate index",
           "0/1/1": "vertex index 0", "99999/1/1": "out of range", "1/1/0": "normal index 0",
           "1/99999": "out of range", "-99999//1": "reaches before the first vertex", "1e3": "not a valid"}


@pytest.mark.parametrize("corner", HOSTILE)
def test_a_hostile_corner_in_a_large_file_is_named_by_its_line(tmp_path, corner):
    lines = _generate(4, 20000).decode().split("\n")
    faces = [i for i, s in enumerate(lines) if s.startswith("f ") and "\\" not in s]
    k = faces[len(faces) // 2]
    words = lines[k].split()
    words[2] = corner
    lines[k] = " ".join(words)
    path = tmp_path / "h.obj"
    path.write_bytes("\n".join(lines).encode())
    with pytest.raises(MeshError, match=f"h.obj: line {k + 1}: .*{re.escape(HOSTILE[corner])}"):
        sf.load(path)
