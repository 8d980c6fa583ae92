"""Hard edges kept as split corner normals (glTF, PLY, USD, OBJ ``vn``) are the file's sharp edges.

The meshes are built here with their normals written by hand: a hexagonal prism whose sides are
shaded smooth (radial normals) and whose caps are flat, so its hard edges are exactly the two
rims (12 edges), by construction.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import run_cli

import shapeflow as sf
from shapeflow.geometry.features import SPLIT_NORMAL_DEGREES, split_normal_edges
from shapeflow.geometry.weld import weld_if_split
from shapeflow.mesh.attributes import Indexed


def prism(split: bool = True, noise: float = 0.0) -> sf.Mesh:
    """A hexagonal prism of 12 vertices, 6 side quads and two hexagonal caps; corner normals radial on
    the sides and ±z on the caps (``split``), or radial-and-tilted everywhere (smooth)."""
    a = np.arange(6) * np.pi / 3
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)
    V = np.concatenate([np.c_[ring, np.zeros(6)], np.c_[ring, np.ones(6)]])
    sides = [[i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i] for i in range(6)]
    faces = sides + [list(range(5, -1, -1)), list(range(6, 12))]
    m = sf.Mesh(V, faces)
    fi = m.face_indices
    radial = np.c_[V[fi, :2], np.zeros(fi.size)]
    rng = np.random.default_rng(1)
    if split:
        N = radial.copy()
        cap = np.repeat(np.arange(m.n_faces), m.face_sizes) >= 6
        N[cap] = np.where((V[fi[cap], 2] > 0.5)[:, None], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0])
    else:
        N = radial + np.c_[np.zeros((fi.size, 2)), 2 * V[fi, 2] - 1]
        N /= np.linalg.norm(N, axis=1)[:, None]
    N = N + noise * rng.standard_normal(N.shape)
    return m.with_corner_attributes(normal=N)


def rim_edges(m: sf.Mesh) -> np.ndarray:
    """The hexagon's sides: same height, length 1 (cap diagonals of a triangulated copy are longer)."""
    e = m.topology.edges
    V = m.vertices
    return (np.abs(V[e[:, 0], 2] - V[e[:, 1], 2]) < 1e-6) & (np.abs(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)
                                                                 - 1.0) < 1e-6)


def test_flat_caps_on_smooth_sides_mark_the_rims_only():
    m = prism()
    assert np.array_equal(split_normal_edges(m), rim_edges(m))
    assert rim_edges(m).sum() == 12


def test_smooth_normals_and_float32_noise_mark_nothing():
    assert not split_normal_edges(prism(split=False)).any()
    # float32 rounding and a file's own small noise stay below the threshold
    noise = 0.1 * np.radians(SPLIT_NORMAL_DEGREES)
    assert not split_normal_edges(prism(split=False, noise=noise)).any()
    assert np.array_equal(split_normal_edges(prism(noise=noise)), rim_edges(prism()))


def test_indexed_normals_and_missing_ones():
    m = prism()
    N = m.corner_attributes["normal"]
    values, index = np.unique(N, axis=0, return_inverse=True)
    idx = index.reshape(-1).copy()
    assert np.array_equal(split_normal_edges(m.with_corner_attributes(normal=Indexed(values, idx))), rim_edges(m))
    # corners without a normal never make an edge sharp
    idx[:] = -1
    assert not split_normal_edges(m.with_corner_attributes(normal=Indexed(values, idx))).any()
    assert not split_normal_edges(m.with_corner_attributes(normal=np.zeros((m.n_corners, 3)))).any()
    assert not split_normal_edges(sf.Mesh.from_csr(m.vertices, m.face_sizes, m.face_indices)).any()


def test_a_gltf_with_split_normals_keeps_its_rims_under_enhancement(tmp_path):
    pytest.importorskip("pygltflib")
    m = prism()
    path = tmp_path / "prism.glb"
    sf.save(path, m)
    back = sf.load(path)
    welded = weld_if_split(back)        # glTF splits a vertex where its normals differ
    assert welded.n_vertices == 12
    marked = split_normal_edges(welded)
    assert np.array_equal(marked, rim_edges(welded))
    out = sf.flow(welded, -3.0, sharp_edges="mesh")
    # each rim is a closed feature curve: its vertices slide along it, in its cap's plane, while the
    # plain enhancement lifts the caps apart (measured 0.31 of the prism's height)
    assert np.abs(out.vertices[:, 2] - welded.vertices[:, 2]).max() < 1e-9
    assert np.abs(out.vertices - welded.vertices).max() > 0.1
    plain = sf.flow(welded, -3.0)
    assert np.abs(plain.vertices[:, 2] - welded.vertices[:, 2]).max() > 0.1


def test_the_command_line_tells_of_split_normals_and_keeps_them(tmp_path, capsys):
    pytest.importorskip("pygltflib")
    src, out = tmp_path / "prism.glb", tmp_path / "out.glb"
    sf.save(src, prism())
    code, _, err = run_cli(["enhance", str(src), str(out), "--strength", "3"], capsys)
    assert code == 0
    assert f"{src} marks 12 sharp edges (split normals); pass --keep-marked-edges to keep them" in err
    code, _, err = run_cli(["enhance", str(src), str(out), "--strength", "3", "--keep-marked-edges", "--force"],
                           capsys)
    assert code == 0 and "marks" not in err
    before, after = sf.load(src), sf.load(out)
    assert np.abs(after.vertices[:, 2] - before.vertices[:, 2]).max() < 1e-6      # float32 file
    assert np.abs(after.vertices - before.vertices).max() > 0.05
    code, text, _ = run_cli(["info", str(src)], capsys)
    assert "12 marked by the file (split normals)" in text
