"""The enhancement brush with sharp edges: a dab never drags a vertex across a sharp edge.

Shapes and the vertex sets that must stay flat, straight or fixed come from tests/flow/feature_shapes.py
(built with NumPy from their construction).  A dab covering the whole mesh must equal flow() with the same
sharp edges; strokes across a nut keep its flat faces, straight edges and corners (the same strokes
without sharp edges bend them, so the checks can fail).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import shapeflow as sf

_spec = importlib.util.spec_from_file_location(
    "feature_shapes", Path(__file__).resolve().parents[1] / "flow" / "feature_shapes.py")
fs = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fs)

EXACT = 1e-9   # × diagonal


plane_dev, line_dev = fs.plane_dev, fs.line_dev


def deviations(mesh, info, V):
    D = mesh.diagonal
    flat = max(plane_dev(V[g]) for g in info["caps"] + info["sides"]) / D
    straight = max(line_dev(V[g]) for g in info["edges"]) / D
    corners = float(np.abs(V[info["corners"]] - mesh.vertices[info["corners"]]).max()) / D
    return flat, straight, corners


@pytest.mark.parametrize("make", [fs.nut, fs.l_bracket])
@pytest.mark.parametrize("opts", [{}, {"normalized": False}, {"weights": "random"}, {"scheme": "blender"}])
@pytest.mark.parametrize("lam", [12.0, -30.0])
def test_a_dab_over_the_whole_mesh_is_the_feature_flow(make, opts, lam):
    mesh, _ = make()
    opts = dict(opts)
    if opts.get("weights") == "random":
        opts["weights"] = np.random.default_rng(2).uniform(0.0, 1.0, mesh.n_vertices)
    brush = sf.Brush(mesh, lam=lam, radius=10.0 * mesh.diagonal, feature_angle=30.0, **opts)
    brush.dab(mesh.vertices.mean(axis=0))
    ref = sf.flow(mesh, lam, feature_angle=30.0, solver="lu", **opts).vertices
    assert np.abs(brush.vertices - ref).max() <= 1e-12 * mesh.diagonal


@pytest.mark.parametrize("lam", [-40.0, 15.0])
def test_strokes_keep_faces_flat_edges_straight_and_corners(lam):
    mesh, info = fs.nut(per_side=6, rings=4, layers=4)
    path = [[1.0, 0.0, 0.6], [0.0, 1.0, 0.6], [-1.0, 0.0, 0.3], [0.0, -0.5, 0.0]]
    brush = sf.Brush(mesh, lam=lam, radius=0.5, feature_angle=30.0)
    moved = brush.stroke(path)
    flat, straight, corners = deviations(mesh, info, brush.vertices)
    assert flat <= EXACT and straight <= EXACT and corners == 0.0
    assert moved.size > 0
    hole = info["hole"]
    assert np.abs(brush.vertices[hole] - mesh.vertices[hole]).max() > 1e-3 * mesh.diagonal
    # the same stroke without sharp edges bends the faces and edges and moves the corners
    plain = sf.Brush(mesh, lam=lam, radius=0.5)
    plain.stroke(path)
    assert min(deviations(mesh, info, plain.vertices)) > 1e-4


def test_feature_vertices_in_a_dab_follow_their_curve_or_stay():
    mesh, info = fs.nut(per_side=6, rings=4, layers=4)
    brush = sf.Brush(mesh, lam=-40.0, radius=0.6, feature_angle=30.0)
    c = np.array([1.0, 0.0, 0.6])                         # a corner of the hexagon, on the top cap
    region = brush.region(c)
    corners = np.intersect1d(info["corners"], region["inside"])
    # a corner inside is kept in place (or it is on the dab's rim, which stays anyway)
    assert np.isin(corners, np.union1d(region["fixed"], region["rim"])).all()
    assert np.isin(corners, region["fixed"]).any()
    top_rim = np.intersect1d(np.concatenate(info["edges"][:12]), info["caps"][1])   # outline of the top cap
    curve_free = np.intersect1d(np.setdiff1d(top_rim, corners), region["free"])
    assert curve_free.size                                  # curve vertices are solved in the dab
    before = mesh.vertices.copy()
    brush.dab(c)
    V = brush.vertices
    assert np.array_equal(V[corners], before[corners])
    # every outline vertex stays on its straight side, in the cap's plane
    assert max(line_dev(V[g]) for g in info["edges"]) <= EXACT * mesh.diagonal
    assert np.abs(V[info["caps"][1], 2] - before[info["caps"][1], 2]).max() <= EXACT * mesh.diagonal


def test_curve_vertices_move_along_a_round_rim():
    # the hole's rim: its vertices inside a dab move (enhancement widens the hole), in the cap's plane
    mesh, info = fs.nut(per_side=6, rings=4, layers=4)
    top = info["caps"][1]
    rim = np.intersect1d(info["hole"], top)
    brush = sf.Brush(mesh, lam=-60.0, radius=0.45, feature_angle=30.0)
    c = mesh.vertices[rim[0]]
    free = np.intersect1d(brush.region(c)["free"], rim)
    assert free.size >= 3
    brush.dab(c)
    V = brush.vertices
    assert np.abs(V[rim, 2] - mesh.vertices[rim, 2]).max() <= EXACT * mesh.diagonal
    r0 = np.hypot(*mesh.vertices[free, :2].T)
    r1 = np.hypot(*V[free, :2].T)
    assert (r1 - r0).max() > 1e-3


def test_nothing_sharp_is_the_plain_brush_bit_for_bit():
    mesh, _ = fs.nut()
    path = [[1.0, 0.0, 0.6], [-1.0, 0.0, 0.3]]
    a = sf.Brush(mesh, lam=-30.0, radius=0.5)
    b = sf.Brush(mesh, lam=-30.0, radius=0.5, feature_angle=180.0)
    a.stroke(path)
    b.stroke(path)
    assert np.array_equal(a.vertices, b.vertices)


@pytest.mark.parametrize("lam_border", [0.0, 3.0])
def test_open_mesh_boundary_and_sharp_edges(lam_border):
    mesh, info = fs.box(per_side=4, layers=4)
    top = set(info["caps"][1].tolist())
    open_box = sf.Mesh(mesh.vertices, [f for f in mesh.faces_as_lists() if not set(f) <= top])
    brush = sf.Brush(open_box, lam=-30.0, lam_border=lam_border, radius=10.0, feature_angle=30.0)
    brush.dab(open_box.vertices.mean(axis=0))
    ref = sf.flow(open_box, -30.0, lam_border=lam_border, feature_angle=30.0, solver="lu").vertices
    assert np.abs(brush.vertices - ref).max() <= 1e-12 * open_box.diagonal
    assert plane_dev(brush.vertices[info["caps"][0]]) <= EXACT * open_box.diagonal
