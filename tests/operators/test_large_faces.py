"""Large faces: validation linear in the corners, the n-gon operator vectorised and bounded."""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow import accel as kernels
from shapeflow.errors import MeshError
from shapeflow.operators.pattern import FAN_TRIANGLES_MAX
from shapeflow.operators.pattern import fan_interior_triangles as _fan_interior_triangles


def ring(k: int, apex: bool = True):
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    V = np.c_[np.cos(t), np.sin(t), 0.1 * np.sin(5 * t)]
    if not apex:
        return V, np.array([k]), np.arange(k)
    V = np.vstack([V, [[0.0, 0.0, 1.0]]])
    fs = np.r_[k, np.full(k, 3)]
    fi = np.r_[np.arange(k), np.c_[np.arange(k), (np.arange(k) + 1) % k, np.full(k, k)].ravel()]
    return V, fs, fi


def fan_definition(s: int):
    """The mean over the s fan triangulations, by enumeration (independent of the library)."""
    acc = {}
    for r in range(s):
        for j in range(1, s - 1):
            tri = (r, (r + j) % s, (r + j + 1) % s)
            key = tuple(sorted(tri))
            acc.setdefault(key, [tri, 0.0])[1] += 1.0 / s
    ears = {tuple(sorted(((k - 1) % s, k, (k + 1) % s))) for k in range(s)}
    keep = [v for k, v in acc.items() if k not in ears]
    return np.array([v[0] for v in keep]).reshape(-1, 3), np.array([v[1] for v in keep])


@pytest.mark.parametrize("s", [5, 6, 7, 9, 16, 31])
def test_fan_triangles_equal_the_definition(s):
    tris, w = _fan_interior_triangles(s)
    ref_t, ref_w = fan_definition(s)
    assert np.array_equal(tris, ref_t) and np.array_equal(w, ref_w)


@pytest.mark.parametrize("use_kernels", [False, True])
@pytest.mark.parametrize("k", [17, 200_000])
def test_validation_of_large_faces(k, use_kernels):
    if use_kernels and not kernels.available():
        pytest.skip("numba (the 'fast' extra) is not installed")
    V, fs, fi = ring(k, apex=False)
    with kernels.enabled(use_kernels):
        assert sf.Mesh.from_csr(V, fs, fi).n_faces == 1
        for pos in (1, k // 2, k - 1):            # a vertex listed twice, early, middle, last
            bad = fi.copy()
            bad[pos] = bad[pos - 1]
            with pytest.raises(MeshError, match="face 0"):
                sf.Mesh.from_csr(V, fs, bad)
    if use_kernels:   # the compiled pass itself, at any size
        from shapeflow.mesh import compiled as K
        offs = np.array([0, k], dtype=np.int64)
        assert K.first_bad_face(fi, offs, V.shape[0]) == -1
        bad = fi.copy()
        bad[-1] = bad[0]
        assert K.first_bad_face(bad, offs, V.shape[0]) == 0


def test_ngon_budget_is_refused_with_the_estimate():
    s = int(np.sqrt(FAN_TRIANGLES_MAX)) + 10
    m = sf.Mesh.from_csr(*ring(s))
    with pytest.raises(MeshError, match=rf"face 0 has {s} corners.*fan triangles \(~[0-9.]+ GB\).*scheme='blender'"):
        sf.flow(m, -5.0)
    out = sf.flow(m, -5.0, scheme="blender")        # corner triangles only: linear, works
    assert np.isfinite(out.vertices).all()


def test_large_ngon_within_budget_matches_explicit_fans():
    # the operator of a 60-gon against the mean of its 60 fan triangulations, built explicitly
    s = 60
    V, fs, fi = ring(s, apex=False)
    V[:, 2] = 0.3 * np.cos(3 * np.linspace(0, 2 * np.pi, s, endpoint=False))   # not planar
    poly = sf.Mesh.from_csr(V, fs, fi)
    W, _ = sf.cotan_weights(poly)
    acc = np.zeros((s, s))
    for r in range(s):
        fan = sf.Mesh(V, [[r, (r + j) % s, (r + j + 1) % s] for j in range(1, s - 1)])
        acc += sf.cotan_weights(fan).W.toarray() / s
    assert np.allclose(W.toarray(), acc, rtol=1e-12, atol=1e-12 * np.abs(acc).max())
