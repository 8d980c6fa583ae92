"""Seams and soups smooth as one surface: weld for the operator, scatter the result back."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MESHES, requires_shared

import shapeflow as sf
from shapeflow.geometry.weld import WELD_TOL, weld_map
from shapeflow.mesh.attributes import Indexed


def soup_of(mesh):
    """Every face with its own copies of its vertices (an unwelded STL)."""
    V = mesh.vertices[mesh.face_indices]
    return sf.Mesh.from_csr(V, mesh.face_sizes, np.arange(V.shape[0]))


def seamed(mesh, cut):
    """Vertices split along a seam, as glTF writes them: faces in ``cut`` get their own copies of
    the vertices they share with the other faces; the UVs index the copies."""
    fi = mesh.face_indices.copy()
    in_cut = np.repeat(cut, mesh.face_sizes)
    shared = np.intersect1d(fi[in_cut], fi[~in_cut])
    new_id = np.full(mesh.n_vertices, -1)
    new_id[shared] = mesh.n_vertices + np.arange(shared.size)
    move = in_cut & np.isin(fi, shared)
    fi[move] = new_id[fi[move]]
    V = np.concatenate([mesh.vertices, mesh.vertices[shared]])
    uv = Indexed(V[:, :2].copy(), fi.copy())
    return sf.Mesh.from_csr(V, mesh.face_sizes, fi, corner_attributes={"uv": uv}), shared


def _tolerance(m, ref):
    """The CG's rtol (1e-8) on the displacement, with a margin of 10: two solves of one system whose
    unknowns are numbered differently agree to that, not to the last bit."""
    return 1e-7 * np.abs(ref.vertices - m.vertices).max()


@requires_shared
def test_a_soup_smooths_like_the_welded_mesh():
    m = sf.load(MESHES / "spot_quad.obj")
    soup = soup_of(m)
    assert soup.n_vertices == m.n_corners and sf.weld(soup).n_vertices == m.n_vertices
    w = sf.weld(soup)
    out = sf.unweld(sf.flow(w, -5.0), soup, w)
    ref = sf.flow(m, -5.0)
    # every copy of a vertex lands where the welded surface puts it, to the solver's tolerance
    # (weld numbers vertices by first use; Gauss–Seidel-preconditioned CG sweeps in vertex order)
    np.testing.assert_allclose(out.vertices, ref.vertices[m.face_indices], rtol=0, atol=_tolerance(m, ref))
    # without welding the operator sees separate faces: a soup does not move as a surface would
    alone = sf.flow(soup, -5.0)
    assert np.abs(alone.vertices - ref.vertices[m.face_indices]).max() > 1e-3


@requires_shared
def test_a_uv_seam_smooths_as_one_surface_and_keeps_its_layout():
    m = sf.load(MESHES / "spot_quad.obj")
    cut = m.vertices[m.face_indices].reshape(-1, 4, 3)[:, :, 0].mean(axis=1) > 0.1   # one side of Spot
    s, shared = seamed(m, cut)
    assert shared.size > 10
    w = sf.weld(s)
    out = sf.unweld(sf.flow(w, -5.0, iterations=2), s, w)
    ref = sf.flow(m, -5.0, iterations=2)
    copies = np.arange(m.n_vertices, s.n_vertices)
    np.testing.assert_allclose(out.vertices[copies], out.vertices[shared], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.vertices[:m.n_vertices], ref.vertices, rtol=0, atol=1e-12)
    assert out.face_indices.tolist() == s.face_indices.tolist()
    assert out.corner_attributes["uv"] == s.corner_attributes["uv"]


def test_weld_drops_faces_whose_corners_coincide_and_keeps_order():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 0, 0.0]])
    m = sf.Mesh(V, [[0, 1, 2], [3, 4, 5], [1, 6, 7]])          # the last face has two equal corners
    w = sf.weld(m)
    assert w.faces_as_lists() == [[0, 1, 2], [1, 3, 2]]
    assert w.weld_map.tolist() == [0, 1, 2, 1, 3, 2, 4, 4] and w.weld_faces.tolist() == [0, 1]
    assert sf.weld(w).n_vertices == w.n_vertices               # welding twice changes nothing
    with pytest.raises(sf.ParameterError, match="tol"):
        sf.weld(m, tol=-1)


def test_the_command_welds_a_soup_and_says_so(tmp_path, capsys):
    from shapeflow.cli import main

    m = sf.load_example("spot")
    soup = soup_of(m)
    sf.save(tmp_path / "soup.ply", soup)
    assert main(["enhance", str(tmp_path / "soup.ply"), str(tmp_path / "out.ply"), "--strength", "5"]) == 0
    err = capsys.readouterr().err
    assert f"{soup.n_vertices - m.n_vertices} vertices coincide" in err
    out = sf.load(tmp_path / "out.ply")
    ref = sf.flow(m, -5.0)
    np.testing.assert_allclose(out.vertices, ref.vertices[m.face_indices], rtol=0, atol=_tolerance(m, ref))
    assert main(["info", str(tmp_path / "soup.ply")]) == 0
    assert f"{soup.n_vertices - m.n_vertices} vertices share a position" in capsys.readouterr().out


def test_subdividing_a_soup_welds_it_first(tmp_path, capsys):
    from shapeflow.cli import main

    m = sf.load_example("spot_cage")
    sf.save(tmp_path / "soup.ply", soup_of(m))
    assert main(["subdivide", str(tmp_path / "soup.ply"), str(tmp_path / "sub.ply")]) == 0
    assert f"welded to {m.n_vertices} before subdividing" in capsys.readouterr().err
    out, ref = sf.load(tmp_path / "sub.ply"), sf.subdivide(m, 1)
    # one connected surface, as the welded cage gives (not separate patches): same points, same faces
    assert out.n_vertices == ref.n_vertices and out.n_faces == ref.n_faces
    np.testing.assert_allclose(np.sort(out.vertices, axis=0), np.sort(ref.vertices, axis=0), atol=1e-12)


def test_the_brush_on_a_soup_counts_the_files_vertices(tmp_path, capsys):
    import json
    import re

    from shapeflow.cli import main

    m = sf.load_example("spot_cage")
    soup = soup_of(m)
    sf.save(tmp_path / "soup.ply", soup)
    (tmp_path / "s.json").write_text(json.dumps({"lambda": -20, "radius": 0.9,
                                                 "points": [m.vertices[0].tolist(), m.vertices[5].tolist()]}))
    assert main(["brush", str(tmp_path / "soup.ply"), str(tmp_path / "out.ply"), "--stroke",
                 str(tmp_path / "s.json")]) == 0
    said = int(re.search(r"(\d+) of (\d+) vertices moved", capsys.readouterr().err).group(1))
    out = sf.load(tmp_path / "out.ply")
    moved = np.flatnonzero(np.any(out.vertices != soup.vertices, axis=1))
    assert said == moved.size > 0
    w = sf.weld(soup)          # every copy of a moved vertex moved
    assert set(moved.tolist()) == set(np.flatnonzero(np.isin(w.weld_map, w.weld_map[moved])).tolist())


# --- any finite scale: the neighbour search runs on an exact power-of-two copy ------------------

def _jittered_soup(seed=0):
    """A closed quad sphere as a soup whose copies of a vertex are moved apart by up to 1e-9 of the
    diagonal (welded at the default 1e-7), and the map that construction implies: each soup vertex
    is its sphere vertex, numbered by first appearance."""
    from meshgen import cube_sphere

    m = cube_sphere(4)
    soup = soup_of(m)
    rng = np.random.default_rng(seed)
    V = soup.vertices + rng.uniform(-1e-9, 1e-9, soup.vertices.shape) * m.diagonal / np.sqrt(3)
    src = m.face_indices
    first = {}
    expected = np.array([first.setdefault(int(v), len(first)) for v in src])
    return V, expected


@pytest.mark.parametrize("scale", [1e-300, 1e-200, 1e-150, 1e-20, 1.0, 1e20, 1e155, 1e200, 1e300,
                                   np.ldexp(1.0, -1020), np.ldexp(1.0, 1000)])
def test_weld_map_is_the_same_at_every_scale(scale):
    V, expected = _jittered_soup()
    assert np.array_equal(weld_map(V, WELD_TOL), expected)
    got = weld_map(V * scale, WELD_TOL)
    assert np.array_equal(got, expected)
    w = sf.weld(sf.Mesh.from_csr(V * scale, np.full(V.shape[0] // 4, 4), np.arange(V.shape[0])))
    assert np.array_equal(w.weld_map, expected) and w.n_vertices == expected.max() + 1


def test_weld_near_its_threshold_is_exact_at_power_of_two_scales():
    """Pairs placed from 0.5 to 2 times the welding distance: some weld, some do not, and scaling
    by 2^k (exact in binary floating point) gives the very same map."""
    rng = np.random.default_rng(3)
    base = rng.uniform(0, 1, (200, 3))
    base[0], base[1] = 0.0, 1.0                      # the box is the unit cube: diagonal sqrt(3)
    d = rng.normal(size=(200, 3))
    d *= (rng.uniform(0.5, 2.0, 200) * WELD_TOL * np.sqrt(3) / np.linalg.norm(d, axis=1))[:, None]
    d[:2] = 0.0
    V = np.concatenate([base, base + d])
    ref = weld_map(V, WELD_TOL)
    welded = ref[200:] == ref[:200]
    assert 20 < welded.sum() < 180                  # both sides of the threshold are exercised
    for k in (-1000, -500, -100, 100, 500, 1020):     # every coordinate stays a normal number
        assert np.array_equal(weld_map(np.ldexp(V, k), WELD_TOL), ref), k


def test_weld_of_coordinates_spanning_the_whole_double_range():
    """±1e308: the bounding-box diagonal itself overflows (inf), the weld is still the shape's."""
    big = np.finfo(float).max / 2
    V = np.array([[-1, -1, -1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1.0]]) * big
    m = sf.Mesh(V, [[0, 2, 1], [0, 1, 3], [4, 5, 3]])
    assert m.diagonal == np.inf
    w = sf.weld(m)
    assert w.weld_map.tolist() == [0, 1, 2, 3, 1, 2] and w.faces_as_lists() == [[0, 2, 1], [0, 1, 3], [1, 2, 3]]
    with pytest.raises(sf.ParameterError, match="vertex 1 has a non-finite coordinate"):
        weld_map(np.array([[0, 0, 0], [np.inf, 0, 0.0]]), 1e-7)


def test_a_million_copies_of_a_point_weld_in_one_sort():
    """Coinciding vertices are merged before the neighbour search: 10⁶ copies of three points would
    be 1.5·10¹¹ pairs for the tree (memory no machine has), here they are three positions."""
    V = np.repeat(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), 1_000_000 // 3 + 1, axis=0)
    wm = weld_map(V, WELD_TOL)
    k = 1_000_000 // 3 + 1
    assert np.array_equal(wm, np.repeat([0, 1, 2], k))


def test_a_dense_cluster_of_distinct_positions_is_refused_by_name():
    """50,000 distinct positions within 1e-9 of the diagonal of each other: 1.25·10⁹ pairs within the
    welding distance.  Refused from a grid count before the search, not after it."""
    rng = np.random.default_rng(5)
    V = np.concatenate([rng.uniform(0, 1e-9, (50_000, 3)), [[1.0, 1.0, 1.0]]])
    with pytest.raises(sf.MeshError, match=r"50,001 distinct vertex positions lie in clusters closer than the "
                                           r"welding distance \(1e-07 × the bounding-box diagonal\)"):
        weld_map(V, WELD_TOL)
