"""Creased Catmull–Clark subdivision against Blender 5.0.1 (tests/data/blender_creases, made by
``benchmarks/blender_ref.py --crease-fixtures``; see the README there).

Level-1 cases are compared in Blender's own vertex and face order; deeper levels as point sets with a
one-to-one matching (Blender evaluates a grid per face, shapeflow refines level by level), the faces
then compared through that matching.  Tolerance 1e-5 of the bounding-box diagonal (Blender works in
float32); these run without Blender.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import shapeflow as sf
from shapeflow.subdivision import subdivide

DATA = Path(__file__).resolve().parents[1] / "data" / "blender_creases"
CASES = sorted(p.stem for p in DATA.glob("*.npz"))
TOL = 1e-5
BOUNDARY = {"ALL": "smooth", "PRESERVE_CORNERS": "keep-corners"}
ROOT = Path(__file__).resolve().parents[2]


def load(case):
    d = np.load(DATA / f"{case}.npz")
    c = {k: d[k] for k in d.files}
    mesh = sf.Mesh.from_csr(c["vertices"], c["face_sizes"], c["face_indices"],
                            weights=c["weights"] if "weights" in c else None)
    return mesh, c


def cyclic(sizes, idx):
    """Faces as a set of tuples, each rotated to start at its smallest vertex."""
    out, o = set(), 0
    for s in sizes.tolist():
        f = idx[o:o + s].tolist()
        k = f.index(min(f))
        out.add(tuple(f[k:] + f[:k]))
        o += s
    return out


def match(ours, theirs, n):
    """ours -> Blender's vertex numbers (old vertices first in both), asserting a one-to-one match."""
    diag = float(np.linalg.norm(np.ptp(theirs, axis=0)))
    assert np.abs(ours[:n] - theirs[:n]).max() <= TOL * diag
    dist, j = cKDTree(theirs[n:]).query(ours[n:])
    assert dist.max() <= TOL * diag, dist.max() / diag
    assert np.unique(j).size == j.size, "the matching is not one-to-one"
    return np.r_[np.arange(n), n + j]


def test_fixtures_exist_and_are_small():
    assert len(CASES) >= 12
    assert sum((DATA / f"{c}.npz").stat().st_size for c in CASES) < 1_000_000
    kinds = {c.split("_")[0] for c in CASES}
    assert {"tri", "quad", "ngon", "open"} <= kinds
    levels = {int(load(c)[1]["levels"]) for c in CASES}
    assert levels == {1, 2, 3}


@pytest.mark.parametrize("case", CASES)
def test_matches_blender(case):
    mesh, c = load(case)
    creases = (c["crease_edges"], c["crease_values"])
    assert (c["crease_values"] > 0).all() and (c["crease_values"] < 1).any()   # semi-sharp creases in every case
    out = subdivide(mesh, int(c["levels"]), boundary=BOUNDARY[str(c["boundary_smooth"])], creases=creases)
    R = c["result"].astype(np.float64)
    assert out.n_vertices == len(R) and out.face_sizes.tolist() == c["result_face_sizes"].tolist()
    diag = float(np.linalg.norm(np.ptp(R, axis=0)))
    if int(c["levels"]) == 1:
        assert np.abs(out.vertices - R).max() <= TOL * diag
        assert np.array_equal(out.face_indices, c["result_face_indices"])
        mapping = np.arange(out.n_vertices)
    else:
        mapping = match(out.vertices, R, mesh.n_vertices)
        assert cyclic(out.face_sizes, mapping[out.face_indices]) == cyclic(c["result_face_sizes"],
                                                                           c["result_face_indices"])
    if "weights" in c:        # vertex weights: Blender's linear rule, whatever the creases
        w = np.empty(out.n_vertices)
        w[mapping] = out.weights
        np.testing.assert_allclose(w, c["result_weights"], atol=1e-6)
    # the same surface without the creases is a different one, and so is the one with Blender's
    # creases read as sharpness 10·c (linear) instead of 10·c²: the fixture tells them apart
    n = mesh.n_vertices
    boundary = BOUNDARY[str(c["boundary_smooth"])]
    plain = subdivide(mesh, int(c["levels"]), boundary=boundary)
    assert np.abs(plain.vertices[:n] - R[:n]).max() > 100 * TOL * diag
    linear = subdivide(mesh, int(c["levels"]), boundary=boundary,
                       creases=(c["crease_edges"], np.sqrt(c["crease_values"].astype(np.float64))))
    assert np.abs(linear.vertices[:n] - R[:n]).max() > 100 * TOL * diag


@pytest.mark.parametrize("case", [c for c in CASES if not c.endswith("_1")])
def test_level_by_level_with_the_carried_creases(case):
    # one level at a time, each continuing from result.creases, reaches Blender's deeper level
    mesh, c = load(case)
    boundary = BOUNDARY[str(c["boundary_smooth"])]
    step = subdivide(mesh, 1, boundary=boundary, creases=(c["crease_edges"], c["crease_values"]))
    for _ in range(int(c["levels"]) - 1):
        step = subdivide(step, 1, boundary=boundary, creases="mesh")
    full = subdivide(mesh, int(c["levels"]), boundary=boundary, creases=(c["crease_edges"], c["crease_values"]))
    assert np.abs(step.vertices - full.vertices).max() <= 1e-12 * mesh.diagonal
    match(step.vertices, c["result"].astype(np.float64), mesh.n_vertices)


# --- live Blender: regenerate one fixture (runs where bpy imports) ---------------------------------

def test_regenerate_a_fixture_with_blender():
    if importlib.util.find_spec("bpy") is None:
        pytest.skip("Blender's bpy module is not installed (pip install bpy==5.0.1, Python 3.11)")
    spec = importlib.util.spec_from_file_location("blender_ref", ROOT / "benchmarks" / "blender_ref.py")
    br = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(br)
    mesh, c = load("open_corners_2")
    P, fs, fi, _, _ = br.subdivision_surface(c["vertices"], c["face_sizes"], c["face_indices"],
                                             levels=int(c["levels"]), boundary_smooth=str(c["boundary_smooth"]),
                                             creases=(c["crease_edges"], c["crease_values"]))
    assert np.array_equal(P.astype(np.float32), c["result"])
    assert np.array_equal(fi, c["result_face_indices"])
