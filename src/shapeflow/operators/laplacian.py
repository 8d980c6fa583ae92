"""The TQLBO Laplacian as a sparse matrix (positive semi-definite: L = I − D⁻¹W or (D − W)/(2A))."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from .cotan import assemble

__all__ = ["laplacian"]


@accel.heavy
def laplacian(mesh: Mesh, normalized: bool = True, scheme: str = "tqlbo", *,
              thresholds: str = "relative") -> sp.csr_matrix:
    """The TQLBO Laplacian as a sparse matrix (positive semi-definite convention).

    ``normalized=True``: eq. 10, ``L = I − D⁻¹W`` (scale-invariant; the paper
    recommends it).  ``normalized=False``: eq. 9, ``L = (D − W) / (2A)`` with
    the ring area A of eq. 5.  Rows of vertices with D = 0 (isolated) or A = 0
    are zero.  ``L @ V`` is zero at interior vertices of planar meshes (linear
    precision) and points away from the neighbour average.
    """
    mesh = as_mesh(mesh)
    pattern, pw, deg, ring, _, _ = assemble(mesh, scheme, thresholds)
    K = pattern.matrix(deg, -pw)
    denom = deg if normalized else 2.0 * ring
    with np.errstate(divide="ignore"):
        s = np.where(denom > 0, 1.0 / np.where(denom > 0, denom, 1.0), 0.0)
    return sp.csr_matrix(sp.diags(s) @ K)
