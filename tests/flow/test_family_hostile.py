"""family() on hostile λ, compiled kernels forced and off: λ so small that σ = 1/|λ| leaves the polynomial
preconditioner's range (and the compiled seed's recurrences meet 0 / 0) or double precision (subnormal λ),
and hundreds of members: no exception, no warning, every member finite and equal to flow() at its λ within
1e-7 of the diagonal."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from meshgen import cube_sphere

import shapeflow as sf
from shapeflow import accel
from shapeflow.linalg import spd

TOL = 1e-7


@pytest.fixture(autouse=True)
def jacobi_flow(monkeypatch):
    """flow() with Jacobi-preconditioned CG, as in tests/flow/test_family.py (the two agree to the
    solves' tolerance)."""
    monkeypatch.setattr(spd, "DEFAULT_PRECONDITIONER", "jacobi")


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("lams", [[1e-200, -1e-100, -5.0, 0.0], list(np.linspace(-300.0, 300.0, 500))],
                         ids=["tiny", "500"])
def test_hostile_families_match_flow(kernels, lams):
    mesh = cube_sphere(6, mix=0.3)
    with accel.use(kernels=kernels), warnings.catch_warnings():
        warnings.simplefilter("error")
        shapes, report = sf.family(mesh, lams, return_report=True)
        assert report.path == "multishift" and np.isfinite(shapes).all()
        refs = {lam: sf.flow(mesh, lam).vertices for lam in set(lams)}
    worst = max(float(np.abs(shapes[m] - refs[lam]).max()) for m, lam in enumerate(lams))
    assert worst <= TOL * mesh.diagonal, worst


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("lams", [[5e-324], [1.0, 5e-324, -1e-308, 3e-309, 0.0, -4.0]], ids=["alone", "mixed"])
def test_subnormal_lams_are_flows(kernels, lams):
    # 1/|λ| overflows below 5.6e-309: such members are solved as flow() does, not handed to the shared
    # solve as an infinite shift (which refused them with "shifts must be finite")
    mesh = cube_sphere(6, mix=0.3)
    tiny = [m for m, lam in enumerate(lams) if lam != 0 and np.isinf(1.0 / abs(lam))]
    with accel.use(kernels=kernels, threads=2), warnings.catch_warnings():
        warnings.simplefilter("error")
        shapes, report = sf.family(mesh, lams, return_report=True)
        refs = np.stack([sf.flow(mesh, lam).vertices for lam in lams])
    assert np.abs(shapes - refs).max() <= TOL * mesh.diagonal
    if len(lams) == 1:
        assert report.path == "separate" and "overflows" in report.reason
    else:
        assert report.path == "multishift" and set(tiny) <= set(report.fallback_members) and len(tiny) == 2
