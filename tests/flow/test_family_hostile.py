"""family() on hostile λ, compiled kernels forced and off: λ so small that σ = 1/|λ| leaves the polynomial
preconditioner's range (and the compiled seed's recurrences meet 0 / 0), and hundreds of members: no
exception, no warning, every member finite and equal to flow() at its λ within 1e-7 of the diagonal."""

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
