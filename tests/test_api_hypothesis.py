"""Any value for any public parameter: a result or a ValueError subclass, nothing else.

A hypothesis strategy of hostile values (NaN, inf, huge and negative numbers,
integers beyond double precision, bools, strings, bytes, None, complex,
arrays of the wrong shape or type, nested lists, callables) is thrown at one
parameter of each public function at a time, the others valid.  Allowed
outcomes: a result (then finite), or an exception that is a ``ValueError``
(every shapeflow error is one).  A ``TypeError``, ``OverflowError``,
``ZeroDivisionError``, ``MemoryError``, ``IndexError``... fails the test.
Values that are valid but costly (many iterations or levels) are left out of
the draw so each example stays small; the limits on those are tested in
``test_limits.py``.
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from meshgen import grid, icosphere

import shapeflow as sf

MESH = icosphere(1)                 # 42 vertices, closed triangles
OPEN = grid(5, 4, mix=0.5, seed=1)   # 20 vertices, quads and triangles, open
N = MESH.n_vertices
_TMP = Path(tempfile.mkdtemp(prefix="shapeflow-hypothesis-"))
atexit.register(shutil.rmtree, _TMP, ignore_errors=True)
_SAVED = _TMP / "saved.ply"
sf.save(_SAVED, MESH)

hostile = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, 2, -1, -(2 ** 63), 2 ** 63, 10 ** 400, -(10 ** 400), 10 ** 9, 1e300, -1e-300, 5e-324]),
    st.integers(-3, 3),
    st.booleans(),
    st.none(),
    st.text(max_size=6),
    st.binary(max_size=6),
    st.complex_numbers(allow_nan=False, max_magnitude=1e6),
    st.sampled_from([complex("nan"), 1j]),
    st.sampled_from(["xyz", "blender", "fixed", "recompute", "cg", "lu", "auto", "tqlbo", "smooth", "weight",
                     "ring", "mixed", "barycentric", "catmull-clark", "simple", "linear", "keep-corners", "chebyshev",
                     "multishift", "separate", "", "x"]),
    st.lists(st.floats(allow_nan=True), max_size=4),
    st.lists(st.lists(st.integers(-2, 2), max_size=3), max_size=3),
    st.sampled_from([np.zeros(N), np.full(N, np.nan), np.full(N, 2.0), np.ones((N, 2)), np.array(["a"] * N),
                     np.zeros(N + 1), np.zeros(0), np.array(1.0), np.array([True, False, True]),
                     np.linspace(0, 1, N).astype(np.float32), np.ones(N, dtype=object), lambda *a: None, object()]),
)

# one row per public call: (name, function of (parameter name, value), parameters)
CALLS = {
    "flow": (lambda kw: sf.flow(MESH, kw.pop("lam", -3.0), **kw),
             ["lam", "lam_border", "iterations", "normalized", "weights", "invert_weights", "preserve_volume",
              "axes", "scheme", "update", "compat", "solver", "rtol", "progress"]),
    "flow_open": (lambda kw: sf.flow(OPEN, kw.pop("lam", -3.0), **{"lam_border": 2.0, **kw}),
                  ["lam", "lam_border", "axes", "preserve_volume", "update"]),
    "smooth": (lambda kw: sf.smooth(MESH, kw.pop("strength", 2.0), **kw), ["strength", "iterations"]),
    "enhance": (lambda kw: sf.enhance(MESH, kw.pop("strength", 2.0), **kw), ["strength", "rtol"]),
    "FlowSolver.run": (lambda kw: sf.FlowSolver(MESH).run(kw.pop("lam", -3.0), **kw),
                       ["lam", "iterations", "preserve_volume", "axes", "update", "progress"]),
    "family": (lambda kw: sf.family(MESH, kw.pop("lams", [0.0, -2.0]), **kw),
               ["lams", "lam_border", "iterations", "normalized", "weights", "preserve_volume", "axes", "scheme",
                "compat", "solver", "rtol", "strategy", "progress", "return_report"]),
    "subdivide": (lambda kw: sf.subdivide(MESH, kw.pop("levels", 1), **kw),
                  ["levels", "scheme", "boundary", "weights_rule"]),
    "cotan_weights": (lambda kw: sf.cotan_weights(MESH, **kw), ["scheme", "thresholds"]),
    "laplacian": (lambda kw: sf.laplacian(MESH, **kw), ["normalized", "scheme"]),
    "mean_curvature": (lambda kw: sf.mean_curvature(MESH, **kw), ["area", "scheme"]),
    "vertex_areas": (lambda kw: sf.vertex_areas(MESH, **kw), ["kind", "scheme"]),
    "Brush": (lambda kw: sf.Brush(MESH, **{"radius": 0.5, **kw}).dab(MESH.vertices[0]),
              ["lam", "radius", "falloff", "lam_border", "weights", "scheme", "normalized", "solver",
               "undo_limit", "rebuild_fraction"]),
    "Brush.stroke": (lambda kw: sf.Brush(MESH, radius=0.5).stroke(
                         kw.pop("points", [MESH.vertices[0], MESH.vertices[5]]), **kw), ["points", "spacing"]),
    "InflateBrush": (lambda kw: sf.InflateBrush(MESH, **{"radius": 0.5, **kw}).dab(MESH.vertices[0]),
                     ["strength", "radius", "falloff", "weights"]),
    "save": (lambda kw: sf.save(_TMP / "m.ply", MESH, **kw), ["binary", "format", "force"]),
    "load": (lambda kw: sf.load(_SAVED, **kw), ["format"]),
    "Mesh": (lambda kw: sf.Mesh(kw.pop("vertices", MESH.vertices), kw.pop("faces", [[0, 1, 2]]), **kw),
             ["vertices", "faces", "weights"]),
}
COSTLY = {"iterations": 50, "levels": 3, "undo_limit": 10 ** 6}   # valid values above these are skipped


def _cheap(name, value) -> bool:
    bound = COSTLY.get(name)
    if bound is None:
        return True
    try:
        return not (float(value.real if isinstance(value, complex) else value) > bound)
    except (TypeError, ValueError, OverflowError):
        return True


@pytest.mark.filterwarnings("error::numpy.exceptions.ComplexWarning")   # a dropped imaginary part is data loss
@pytest.mark.parametrize("call", sorted(CALLS))
@settings(max_examples=120, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=st.data())
def test_any_value_gives_a_result_or_a_value_error(call, data):
    fn, names = CALLS[call]
    name = data.draw(st.sampled_from(names), label="parameter")
    value = data.draw(hostile.filter(lambda v: _cheap(name, v)), label="value")
    try:
        out = fn({name: value})
    except ValueError:
        return
    arrays = [out] if isinstance(out, np.ndarray) else []
    if isinstance(out, sf.Mesh):
        arrays = [out.vertices]
    for a in arrays:
        if a.dtype.kind == "f":
            assert np.isfinite(a).all(), (call, name, value)
