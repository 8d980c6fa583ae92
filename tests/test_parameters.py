"""Public parameters: every bad value is a ParameterError naming the parameter; huge λ works or is refused.

Large |λ|: one step tends to its limit, the weighted mean of every free part
(smoothing) or its reflection (enhancement), derived from
(C + D − W) V' = C V with C = D/|λ| → 0 and 1ᵀ(D − W) = 0: the D-weighted
mean is conserved exactly and everything else decays like 1/|λ|.
"""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow import params
from shapeflow.errors import ParameterError


@pytest.mark.parametrize("compat", [None, "blender"])
@pytest.mark.parametrize("solver", ["auto", "cg", "lu"])
@pytest.mark.parametrize("lam", [1e12, -1e12, 1e10])
def test_huge_lambda_reaches_the_limit(spot, lam, solver, compat):
    out = sf.flow(spot, lam, solver=solver, compat=compat)
    W, _ = sf.cotan_weights(spot, scheme="blender" if compat else "tqlbo")
    D = np.asarray(W.sum(axis=1)).ravel()
    mean = D @ spot.vertices / D.sum()
    limit = np.broadcast_to(mean, spot.vertices.shape) if lam > 0 else 2.0 * spot.vertices - mean
    disp = np.abs(limit - spot.vertices).max()
    assert np.isfinite(out.vertices).all()
    # the conserved mean to rounding, the rest within O(1/|λ|) of the limit
    assert np.abs(D @ out.vertices / D.sum() - D @ limit / D.sum()).max() <= 1e-12 * disp
    assert np.abs(out.vertices - limit).max() <= 1e-5 * disp


@pytest.mark.parametrize("lam", [1e12, -1e12])
def test_huge_lambda_with_a_fixed_border_is_harmonic(lam):
    # λ_b = 0 holds the border: the limit solves (D − W) x = 0 on the interior rows (dense, here)
    from meshgen import grid

    mesh = grid(12, 9, jitter=0.2, seed=3, mix=0.5)
    mesh = mesh.with_vertices(mesh.vertices + np.c_[0 * mesh.vertices[:, :2],
                                                    np.sin(3 * mesh.vertices[:, 0]) * mesh.vertices[:, 1]])
    W, _ = sf.cotan_weights(mesh)
    L = (np.diag(np.asarray(W.sum(axis=1)).ravel()) - W.toarray())
    b = mesh.topology.boundary_vertex_mask
    f = ~b
    x = mesh.vertices.copy()
    x[f] = np.linalg.solve(L[np.ix_(f, f)], -L[np.ix_(f, b)] @ mesh.vertices[b])
    limit = x if lam > 0 else 2.0 * mesh.vertices - x
    out = sf.flow(mesh, lam)
    disp = np.abs(limit - mesh.vertices).max()
    assert np.abs(out.vertices - limit).max() <= 1e-6 * disp


@pytest.mark.parametrize("call", [
    lambda m: sf.flow(m, 1e13),
    lambda m: sf.flow(m, -1e300),
    lambda m: sf.flow(m, 1.0, lam_border=2e12),
    lambda m: sf.family(m, [1.0, -5e12]),
    lambda m: sf.FlowSolver(m).run(-1e16),
])
def test_lambda_beyond_the_bound_is_refused(spot, call):
    with pytest.raises(ParameterError, match=r"must be <= 1e\+12"):
        call(spot)


BAD = [
    ("lam", 10 ** 400), ("lam", "1"), ("lam", b"1"), ("lam", True), ("lam", None), ("lam", float("nan")),
    ("lam", 1 + 2j), ("lam", [1.0]),
    ("rtol", 0), ("rtol", None), ("rtol", -1e-8), ("rtol", 1.0), ("rtol", float("inf")), ("rtol", "1e-8"),
    ("iterations", 10 ** 9), ("iterations", 1.0), ("iterations", True), ("iterations", -1),
    ("preserve_volume", "no"), ("preserve_volume", 1), ("preserve_volume", None),
    ("normalized", "yes"), ("invert_weights", 0),
    ("axes", (True, float("nan"), True)), ("axes", (1, 2, 0)), ("axes", "xw"), ("axes", b"xy"),
    ("axes", 3), ("axes", (True, True)),
    ("lam_border", 10 ** 400), ("lam_border", "0"),
    ("update", ["fixed"]), ("solver", ["cg"]), ("compat", ["blender"]), ("scheme", 3),
    ("weights", [10 ** 400] * 3), ("weights", "no such attribute"), ("weights", np.full(3, np.nan)),
    ("progress", "yes"),
]


@pytest.mark.parametrize("name,value", BAD, ids=[f"{n}={v!r}"[:40] for n, v in BAD])
def test_flow_parameters_are_validated(name, value):
    mesh = sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    kw = {"lam": 1.0, name: value}
    lam = kw.pop("lam")
    with pytest.raises(ParameterError, match=name.split("[")[0] if name != "weights" else "weights|attribute"):
        sf.flow(mesh, lam, **kw)


def test_good_scalars_of_every_kind_pass(spot):
    for v in (1, 1.0, np.float32(1.0), np.int64(1), np.array(1.0)):
        assert params.number("x", v) == 1.0
    assert params.flag("f", np.bool_(True)) is True
    assert list(params.axes([1, 0, np.True_])) == [True, False, True]
