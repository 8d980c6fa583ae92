"""Extreme coordinate scales: the flow, curvature and normals work (exact power-of-two rescaling) or refuse.

References: the flow is scale-equivariant (eq. 10 and the umbrella step are
scale-free; eq. 9's λ scales with the area), and scaling by a power of two is
exact in binary floating point, so at scale 2^k the results must equal 2^k
times those at scale 1 bit for bit; curvature scales as 2^-k.
"""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.errors import ParameterError


@pytest.fixture(scope="module")
def open_mesh():
    from meshgen import grid

    return grid(9, 7, jitter=0.2, seed=5, mix=0.4, z=lambda x, y: 0.3 * np.sin(x) * np.cos(y))


# eq. 9 at scale 2^k takes λ·4^k: k = -400, -200 keep it representable and under the bound
@pytest.mark.parametrize("k,normalized", [(-900, True), (-400, True), (200, True), (400, True), (900, True),
                                          (-400, False), (-200, False)])
def test_flow_at_power_of_two_scales_is_exact(spot, k, normalized):
    small = sf.flow(spot, -5.0, normalized=normalized, iterations=2)
    big_mesh = spot.with_vertices(np.ldexp(spot.vertices, k))
    lam = -5.0 if normalized else float(np.ldexp(-5.0, 2 * k))   # eq. 9: C = 2A/(|λ|w), A scales by 4^k
    big = sf.flow(big_mesh, lam, normalized=normalized, iterations=2)
    assert np.array_equal(big.vertices, np.ldexp(small.vertices, k))
    assert big.report.max_displacement == np.ldexp(small.report.max_displacement, k)
    assert big.report.locked == small.report.locked == 0


@pytest.mark.parametrize("k", [-600, 600])
def test_open_mesh_with_border_and_volume_at_extreme_scales(open_mesh, k):
    kw = dict(lam_border=3.0, iterations=2, preserve_volume=False)
    small = sf.flow(open_mesh, -4.0, **kw)
    big = sf.flow(open_mesh.with_vertices(np.ldexp(open_mesh.vertices, k)), -4.0, **kw)
    assert np.array_equal(big.vertices, np.ldexp(small.vertices, k))


@pytest.mark.parametrize("k", [-900, -300, 300, 900])
def test_family_at_extreme_scales(spot, k):
    lams = [0.0, -5.0, -20.0]
    small = sf.family(spot, lams)
    big = sf.family(spot.with_vertices(np.ldexp(spot.vertices, k)), lams)
    assert np.array_equal(big, np.ldexp(small, k))


@pytest.mark.parametrize("scale", [1e-300, 1e-150, 1e155, 1e300])
def test_curvature_and_normals_at_extreme_scales(spot, scale):
    H = sf.mean_curvature(spot, area="barycentric")
    m = spot.with_vertices(spot.vertices * scale)
    Hs = sf.mean_curvature(m, area="barycentric")
    assert np.isfinite(Hs).all()
    assert np.allclose(Hs * scale, H, rtol=1e-9, atol=1e-9 * np.abs(H).max())
    from shapeflow.geometry import vertex_normals

    assert np.allclose(vertex_normals(m), vertex_normals(spot), atol=1e-12)


def test_areas_beyond_double_precision_are_refused(spot):
    m = spot.with_vertices(spot.vertices * 1e200)
    with pytest.raises(ParameterError, match="areas beyond double precision"):
        sf.cotan_weights(m)
    with pytest.raises(ParameterError, match="areas beyond double precision"):
        sf.vertex_areas(m)


def test_blender_mode_refuses_coordinates_beyond_float32(spot):
    with pytest.raises(ParameterError, match="float32"):
        sf.flow(spot.with_vertices(spot.vertices * 1e80), -5.0, compat="blender")


def test_enhancement_beyond_double_precision_is_refused(spot):
    m = spot.with_vertices(spot.vertices * 5e307)    # λ = −1e6 moves Spot's farthest vertex ~7× out
    with pytest.raises(ParameterError, match="range of double precision"):
        sf.flow(m, -1e6, iterations=3)


def test_report_says_when_a_rebuilt_operator_leaves_nothing_free(spot, monkeypatch):
    from shapeflow.flow.system import SystemBuilder

    real = SystemBuilder.interior
    calls = []

    def second_time_nothing_free(self, *a, **k):
        calls.append(1)
        return real(self, *a, **k) if len(calls) == 1 else None

    monkeypatch.setattr(SystemBuilder, "interior", second_time_nothing_free)
    out = sf.flow(spot, -5.0, iterations=4, update="recompute")
    assert out.report.steps == 1 and out.report.max_displacement > 0
    assert any("stopped after 1 of 4 steps" in n for n in out.report.notes)
    assert not any("input returned unchanged" in n for n in out.report.notes)
    monkeypatch.undo()
    assert sf.flow(spot, -5.0, iterations=3).report.steps == 3
