"""Figure 5 end to end: coarse cage + painted weights → Catmull–Clark → smooth → weighted enhance."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MESHES, requires_shared

import shapeflow as sf


@requires_shared
@pytest.mark.parametrize("weights_rule", ["linear", "smooth"])
def test_figure5_pipeline(weights_rule):
    cage = sf.load(MESHES / "spot_control_hybrid.obj")      # triangles, quads, pentagons
    v = cage.vertices
    # paint: full weight on the front third, zero on the back half, nothing in between
    x = (v[:, 2] - v[:, 2].min()) / np.ptp(v[:, 2])
    w = np.clip((x - 0.5) * 6.0, 0.0, 1.0)
    cage = cage.with_weights(w)
    fine = sf.subdivide(cage, 2, weights_rule=weights_rule)
    assert set(fine.face_count_by_size()) == {4}
    wf = fine.weights
    assert wf is not None and wf.shape == (fine.n_vertices,)
    assert (wf >= 0).all() and (wf <= 1).all()
    # weights follow the cage: original vertices keep theirs (linear rule)
    if weights_rule == "linear":
        np.testing.assert_array_equal(wf[:cage.n_vertices], w)
    smoothed = sf.smooth(fine, 5.0)
    enhanced = sf.enhance(smoothed, 60.0, weights="weight", lam_border=0.0)
    zero = wf == 0
    assert zero.sum() > 0.3 * fine.n_vertices
    assert np.array_equal(enhanced.vertices[zero], smoothed.vertices[zero])
    moved = np.linalg.norm(enhanced.vertices - smoothed.vertices, axis=1)
    assert moved[wf == 1].min() > 0
    assert moved[wf == 1].mean() > 1e-3 * fine.diagonal
    assert np.isfinite(enhanced.vertices).all()
