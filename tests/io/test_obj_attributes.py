"""OBJ keeps what production assets carry: vt, vn, usemtl, g, o, s, mtllib, comments, colours.

The reference reader below is written here, line by line, independently of shapeflow's
vectorised one; every round trip is checked against it.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import MESHES, requires_shared

import shapeflow as sf
from shapeflow.errors import DataLossWarning
from shapeflow.mesh.attributes import Indexed


def reference_read(path):
    """A plain, line-by-line OBJ reader: positions, vt, vn, faces as (v, vt, vn) 0-based triples
    (-1 for none), and the state (usemtl, g, o, s) in force at each face."""
    v, vt, vn, faces, state, mtllib = [], [], [], [], [], []
    cur = {"usemtl": "", "g": "", "o": "", "s": ""}
    for raw in open(path, encoding="utf-8"):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tag, *rest = line.split()
        if tag == "v":
            v.append([float(x) for x in rest[:3]])
        elif tag == "vt":
            vt.append([float(x) for x in rest])
        elif tag == "vn":
            vn.append([float(x) for x in rest])
        elif tag == "f":
            corners = []
            for tok in rest:
                parts = (tok.split("/") + ["", ""])[:3]
                idx = []
                for p, table in zip(parts, (v, vt, vn)):
                    if p == "":
                        idx.append(-1)
                    else:
                        i = int(p)
                        idx.append(i - 1 if i > 0 else len(table) + i)
                corners.append(tuple(idx))
            faces.append(corners)
            state.append(dict(cur))
        elif tag in cur:
            cur[tag] = " ".join(rest)
        elif tag == "mtllib":
            mtllib.append(" ".join(rest))
    return dict(v=np.array(v), vt=vt, vn=vn, faces=faces, state=state, mtllib=mtllib)


def assert_matches_reference(mesh, ref, *, positions=True, normals=True):
    if positions:
        np.testing.assert_array_equal(mesh.vertices, ref["v"])
    assert mesh.n_faces == len(ref["faces"])
    fi = mesh.face_indices
    assert fi.tolist() == [c[0] for f in ref["faces"] for c in f]
    uv = mesh.corner_attributes.get("uv")
    if ref["vt"]:
        assert isinstance(uv, Indexed)
        assert uv.index.tolist() == [c[1] for f in ref["faces"] for c in f]
        np.testing.assert_array_equal(uv.values, np.array(ref["vt"]))
    nrm = mesh.corner_attributes.get("normal")
    if ref["vn"]:
        assert nrm.index.tolist() == [c[2] for f in ref["faces"] for c in f]
        if normals:
            np.testing.assert_array_equal(nrm.values, np.array(ref["vn"]))
    for tag, attr in (("usemtl", "material"), ("g", "group"), ("o", "object"), ("s", "smooth")):
        want = [s[tag] for s in ref["state"]]
        if any(want):
            assert mesh.face_attributes[attr].values().tolist() == want, tag
    assert list(mesh.metadata.get("obj", {}).get("mtllib", [])) == ref["mtllib"]


SAMPLE = """# a hand-made asset
mtllib shop.mtl
o crate
v 0 0 0 1 0 0
v 1 0 0 0 1 0
v 1 1 0 0 0 1
v 0 1 0 1 1 0
v 0.5 0.5 1 0.5 0.5 0.5
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5
vn 0 0 -1
vn 0 0 1
g bottom
usemtl wood
s off
f 1/1/1 4/4/1 3/3/1 2/2/1
g top
usemtl metal
s 1
f 1/1/2 2/2/2 5/5/2
f 2/2/2 3/3/2 -1/-1/2
f 3/3/2 4/4/2 5/5/-1
f 4//2 1//2 5//2
l 1 2
"""


@pytest.fixture
def sample(tmp_path):
    p = tmp_path / "crate.obj"
    p.write_text(SAMPLE)
    return p


def test_everything_is_read(sample):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataLossWarning)      # nothing in the sample is lost
        m = sf.load(sample)
    assert_matches_reference(m, reference_read(sample))
    np.testing.assert_array_equal(m.attributes["color"][:2], [[1, 0, 0], [0, 1, 0]])
    assert m.metadata["obj"]["comments"] == ["a hand-made asset"]
    assert m.metadata["obj"]["dropped"] == {}
    assert [tag for tag, _ in m.metadata["obj"]["elements"]] == ["l"]
    assert m.face_attributes["object"].values().tolist() == ["crate"] * 5


def test_round_trip_keeps_everything(sample, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        m = sf.load(sample)
    out = tmp_path / "out.obj"
    sf.save(out, m)
    back = sf.load(out)
    assert back == m
    assert_matches_reference(back, reference_read(out))
    assert "mtllib shop.mtl" in out.read_text()


def test_flow_moves_positions_keeps_uvs_and_groups_and_recomputes_normals(sample, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        m = sf.load(sample)
    out = sf.flow(m, -2.0, lam_border=0.5)
    assert not np.array_equal(out.vertices, m.vertices)
    assert out.corner_attributes["uv"] == m.corner_attributes["uv"]
    for k in ("material", "group", "object", "smooth"):
        assert out.face_attributes[k] == m.face_attributes[k]
    assert any("normals recomputed" in n for n in out.report.notes)
    # the split normals keep their splits: entry 0 is used by the bottom face only, entry 1 by the
    # top faces; each is the unit sum of the vector areas of its faces (derived here independently)
    nrm = out.corner_attributes["normal"]
    assert nrm.index.tolist() == m.corner_attributes["normal"].index.tolist()
    V = out.vertices
    for entry in (0, 1):
        acc = np.zeros(3)
        for f in range(out.n_faces):
            ids = out.face(f)
            corners = range(out.face_offsets[f], out.face_offsets[f + 1])
            if any(nrm.index[c] == entry for c in corners):
                p = V[ids]
                acc += 0.5 * sum(np.cross(p[k] - p[0], p[k + 1] - p[0]) for k in range(1, len(ids) - 1))
        np.testing.assert_allclose(nrm.values[entry], acc / np.linalg.norm(acc), atol=1e-12)
    sf.save(tmp_path / "moved.obj", out)
    assert_matches_reference(sf.load(tmp_path / "moved.obj"), reference_read(tmp_path / "moved.obj"),
                             positions=False)


@requires_shared
@pytest.mark.parametrize("name", ["bob_quad", "spot_quad", "spot_tri"])
def test_shared_assets_round_trip(name, tmp_path):
    path = MESHES / f"{name}.obj"
    m = sf.load(path)
    assert_matches_reference(m, reference_read(path))
    assert "uv" in m.corner_attributes
    out = tmp_path / f"{name}.obj"
    sf.save(out, sf.flow(m, -5.0))
    back = sf.load(out)
    assert_matches_reference(back, reference_read(out))
    assert back.corner_attributes["uv"] == m.corner_attributes["uv"]
    for k in m.face_attributes:
        assert back.face_attributes[k] == m.face_attributes[k]


def test_subdivision_interpolates_uvs_face_varying(sample):
    """Linear face-varying rule, checked on every child corner: at an old vertex the parent corner's
    value, at an edge point the mean of the edge's two corner values in the face, at the face point
    the mean of the face's corner values.  Simple subdivision puts edge points at edge midpoints,
    which tells the test which edge a child corner sits on."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        m = sf.load(sample)
    s = sf.subdivide(m, 1, scheme="simple")
    pu = m.corner_attributes["uv"]
    cu = s.corner_attributes["uv"].expand()
    t = m.topology
    V, fi = m.vertices, m.face_indices
    for c in range(t.n_corners):
        f = int(t.corner_face[c])
        corners = np.arange(m.face_offsets[f], m.face_offsets[f + 1])
        nxt, prv = int(t.corner_next[c]), int(t.corner_prev[c])
        candidates = {   # position of the child vertex -> the parent corners whose values it mixes
            tuple(V[fi[c]]): [c],
            tuple(0.5 * (V[fi[c]] + V[fi[nxt]])): [c, nxt],
            tuple(0.5 * (V[fi[prv]] + V[fi[c]])): [prv, c],
            tuple(V[fi[corners]].mean(axis=0)): list(corners),
        }
        for j in range(4):
            pos = tuple(s.vertices[s.face_indices[4 * c + j]])
            mix = next(v for k, v in candidates.items() if np.allclose(k, pos, atol=1e-15))
            ids = pu.index[mix]
            if (ids >= 0).all():
                np.testing.assert_allclose(cu[4 * c + j], pu.values[ids].mean(axis=0), atol=1e-15)
            else:
                assert np.isnan(cu[4 * c + j]).all()
    for k in m.face_attributes:
        assert s.face_attributes[k].values().tolist() == np.repeat(m.face_attributes[k].values(),
                                                                    m.face_sizes).tolist()


def test_a_point_cloud_is_refused_by_the_commands_and_named_by_info(tmp_path, capsys):
    from shapeflow.cli import main

    p = tmp_path / "cloud.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    assert main(["smooth", str(p), str(tmp_path / "out.obj"), "--strength", "1"]) == 2
    err = capsys.readouterr().err
    assert "no faces" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out.obj").exists()
    assert main(["info", str(p)]) == 0
    out = capsys.readouterr().out
    assert "point cloud" in out and "closed" not in out and "manifold" not in out


def test_the_command_line_names_what_it_cannot_keep(sample, tmp_path, capsys):
    from shapeflow.cli import main

    assert main(["smooth", str(sample), str(tmp_path / "out.obj"), "--strength", "1", "-q"]) == 0
    assert capsys.readouterr().err == ""                     # the polyline is written back
    polylines = [ln for ln in sample.read_text().splitlines() if ln.startswith("l ")]
    assert [ln for ln in (tmp_path / "out.obj").read_text().splitlines() if ln.startswith("l ")] == polylines
    assert main(["subdivide", str(sample), str(tmp_path / "sub.obj"), "-q"]) == 0
    assert "'l'/'p'/'t' lines refer to the input's vertex numbering" in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        back, m = sf.load(tmp_path / "out.obj"), sf.load(sample)
    assert back.corner_attributes["uv"] == m.corner_attributes["uv"]
    assert back.face_attributes["material"] == m.face_attributes["material"]


@requires_shared
def test_concatenate_joins_attributes_and_names_what_it_cannot(tmp_path):
    a, b = sf.load(MESHES / "bob_quad.obj"), sf.load(MESHES / "spot_quad.obj")
    only_a = sorted(set(a.face_attributes) - set(b.face_attributes))
    with pytest.warns(DataLossWarning, match="face attribute") as rec:
        c = sf.mesh.concatenate([a, b])
    assert all(f"face attribute '{k}'" in str(rec[0].message) for k in only_a)
    np.testing.assert_array_equal(c.corner_attributes["uv"].expand(),
                                  np.concatenate([a.corner_attributes["uv"].expand(),
                                                  b.corner_attributes["uv"].expand()]))
    both = sf.mesh.concatenate([a, a])
    assert both.face_attributes["material"].values().tolist() == 2 * a.face_attributes["material"].values().tolist()
    assert both.corner_attributes["normal"].index.max() == 2 * a.corner_attributes["normal"].values.shape[0] - 1
