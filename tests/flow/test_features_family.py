"""Families with sharp edges: one multi-shift BiCG solve for every λ, each member equal to flow() (1e-7
of the diagonal); and the BiCG itself against dense solves."""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.flow.family_features import multishift_bicg

paths = importlib.import_module("shapeflow.flow.family_paths")
_spec = importlib.util.spec_from_file_location("feature_shapes", Path(__file__).with_name("feature_shapes.py"))
fs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fs)

LAMS = [0.0, -5.0, 5.0, -50.0, -120.0, 30.0, 0.0, -235.0]
TOL = 1e-7    # × diagonal


def open_box():
    mesh, info = fs.box(per_side=3, layers=3, split=0.2)
    top = set(info["caps"][1].tolist())
    return sf.Mesh(mesh.vertices, [f for f in mesh.faces_as_lists() if not set(f) <= top])


def _agree(mesh, lams, **opts):
    shapes, report = sf.family(mesh, lams, return_report=True, **opts)
    worst = 0.0
    for m, lam in enumerate(lams):
        ref = sf.flow(mesh, lam, **opts).vertices
        worst = max(worst, float(np.abs(shapes[m] - ref).max()) / mesh.diagonal)
    assert worst <= TOL, worst
    return report


MESHES = {"nut": lambda: fs.nut()[0], "l_bracket": lambda: fs.l_bracket(split=0.3)[0],
          "box_mixed": lambda: fs.box(split=0.3, hexagons=2)[0], "open_box": open_box}


@pytest.mark.parametrize("name", MESHES)
@pytest.mark.parametrize("variant", ["plain", "weights", "blender", "volume", "border", "given_edges"])
def test_family_with_sharp_edges_is_one_solve_and_equals_flow(name, variant):
    mesh = MESHES[name]()
    w = np.random.default_rng(3).uniform(0.0, 1.0, mesh.n_vertices)
    w[::9] = 0.0
    opts = {"plain": {"feature_angle": 30.0},
            "weights": {"feature_angle": 30.0, "weights": w},
            "blender": {"feature_angle": 30.0, "compat": "blender", "lam_border": 1.0},
            "volume": {"feature_angle": 30.0, "preserve_volume": True, "axes": "xz"},
            "border": {"feature_angle": 30.0, "lam_border": -2.0},
            "given_edges": {"sharp_edges": mesh.topology.edges[sf.geometry.features.angle_sharp_edges(mesh, 50.0)]},
            }[variant]
    report = _agree(mesh, LAMS, **opts)
    assert report.path == "multishift", report.reason
    assert report.solver == "multishift-bicg"
    assert report.fallback_members == []
    assert report.shifts == 5 and report.krylov_iterations > 0
    assert "one multi-shift BiCG solve for 5 distinct" in report.summary()


def test_several_iterations_are_solved_per_member():
    mesh = MESHES["nut"]()
    report = _agree(mesh, [-5.0, 20.0], feature_angle=30.0, iterations=2)
    assert report.path == "separate"


def test_extreme_coordinates_keep_their_sharp_edges():
    mesh = fs.nut()[0]
    big = mesh.with_vertices(np.ldexp(mesh.vertices, 300))
    shapes = sf.family(big, [-10.0, 5.0], feature_angle=30.0)
    for s, lam in zip(shapes, (-10.0, 5.0)):
        ref = sf.flow(big, lam, feature_angle=30.0).vertices
        assert np.abs(s - ref).max() <= TOL * big.diagonal
        # the flow is scale-equivariant: the small nut's flow, scaled, to the solver's tolerance
        small = np.ldexp(sf.flow(mesh, lam, feature_angle=30.0).vertices, 300)
        assert np.abs(small - ref).max() <= 1e-9 * big.diagonal


def test_extreme_coordinates_keep_carried_creases_and_angles():
    # a subdivision's creases ride on the mesh object; the flow's scaled copy must still see them
    mesh = fs.box(per_side=2, layers=2)[0]
    part = sf.subdivide(mesh, 1, creases=(mesh.topology.edges[sf.geometry.features.angle_sharp_edges(mesh, 45.0)],
                                          1.0))
    big = part.with_vertices(np.ldexp(part.vertices, 400))
    big.creases = part.creases
    for kernels in ("force", "off"):
        with sf.accel.use(kernels=kernels):
            assert np.array_equal(sf.geometry.features.angle_sharp_edges(big, 45.0),
                                  sf.geometry.features.angle_sharp_edges(part, 45.0))
    a = sf.flow(big, -5.0, sharp_edges="mesh")
    b = sf.flow(part, -5.0, sharp_edges="mesh")
    assert a.report.sharp_edges == b.report.sharp_edges > 0
    assert np.abs(np.ldexp(a.vertices, -400) - b.vertices).max() <= 1e-9 * part.diagonal


def test_unconverged_members_are_redone(monkeypatch):
    mesh = fs.nut()[0]
    real = multishift_bicg
    runs = []

    def capped(*a, **kw):
        res = real(*a, **{**kw, "maxiter": 20})
        runs.append(res)
        return res

    monkeypatch.setattr(paths, "multishift_bicg", capped)
    lams = [-1.0, -150.0, -400.0]
    report = _agree(mesh, lams, feature_angle=30.0)
    (res,) = runs
    unconverged = ~res.converged.all(axis=1)
    assert unconverged.any() and not unconverged.all()
    assert report.fallback_members            # redone by flow(), which _agree checked


@pytest.mark.parametrize("seed", [0, 1])
def test_multishift_bicg_against_dense_solves(seed):
    # a block lower-triangular system like the flow's (an SPD curve block, an SPD surface block,
    # a coupling from the curves into the surface), shifted by several σ
    rng = np.random.default_rng(seed)
    n1, n2 = 12, 40

    def spd(k):
        Q = rng.normal(size=(k, k))
        return Q @ Q.T / k + 0.1 * np.eye(k)

    M = np.zeros((n1 + n2, n1 + n2))
    M[:n1, :n1] = spd(n1)
    M[n1:, n1:] = spd(n2)
    M[n1:, :n1] = -0.3 * rng.random((n2, n1))
    B = rng.normal(size=(3, n1 + n2))
    shifts = np.array([0.05, 0.5, 0.05, 2.0, 10.0])
    res = multishift_bicg(M, M.T.copy(), B, shifts, rtol=1e-10, maxiter=500)
    assert res.converged.all()
    for i, s in enumerate(shifts):
        X = np.linalg.solve(M + s * np.eye(n1 + n2), B.T).T
        np.testing.assert_allclose(res.X[:, i], X, rtol=0, atol=1e-8 * np.abs(X).max())
    # the seed (smallest shift) took the most iterations
    assert res.iterations[0].max() == res.iterations.max()
