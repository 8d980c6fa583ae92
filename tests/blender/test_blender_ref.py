"""The Blender harness (benchmarks/blender_ref.py) against the Blender fixtures.

Needs Blender as a Python module (``pip install bpy==5.0.1``, Python 3.11);
the tests that run Blender skip without it.
"""

from __future__ import annotations

import importlib.util
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import FIXTURES, ROOT, fixture_cases, load_fixture_case, need, requires_shared

HARNESS = ROOT / "benchmarks" / "blender_ref.py"
TOL = 1e-6  # × bounding-box diagonal; it is the same Blender, so this is ~0 in practice

LAPLACIAN_CASES = [
    "smooth_torus_0",  # closed quads, enhance (λ < 0)
    "smooth_suzanne_hybrid_3",  # mixed tri/quad, 3 iterations
    "smooth_cylinder_ngon_4",  # n-gon caps, area-normalised (use_normalized=False)
    "smooth_suzanne_6",  # use_volume_preserve, 3 iterations
    "smooth_grid_open_3",  # open mesh, lambda_border = 0.5
    "smooth_grid_open_8",  # open mesh, lambda_border = 1.0, inverted random weights
    "smooth_uv_sphere_7",  # vertex-group weights (ramp_z)
]
SUBDIV_CASES = [
    "subdiv_grid_open_catmull_clark_preserve_corners_2",
    "subdiv_suzanne_hybrid_catmull_clark_all_1",
    "subdiv_cylinder_ngon_simple_all_1",
]


def _load_harness():
    spec = importlib.util.spec_from_file_location("blender_ref", HARNESS)
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("blender_ref", mod)
    spec.loader.exec_module(mod)
    return sys.modules["blender_ref"]


@pytest.fixture(scope="module")
def br():
    need("bpy", "Blender's bpy module (pip install bpy==5.0.1, Python 3.11)")
    return _load_harness()


def _mesh_arrays(name):
    d = np.load(FIXTURES / "meshes" / f"{name}.npz")
    return d["vertices"], d["face_sizes"], d["face_indices"]


def _diag(p):
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))


def test_harness_imports_without_bpy():
    # A fresh interpreter where importing bpy fails: the module must still import.
    code = (
        "import sys, importlib.util; sys.modules['bpy'] = None\n"
        f"spec = importlib.util.spec_from_file_location('blender_ref', {str(HARNESS)!r})\n"
        "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)\n"
        "assert m.available() is False\n"
        "for f in ('make_object', 'laplacian_smooth', 'subdivision_surface', 'clear_scene', 'suzanne_sub4', 'main'):\n"
        "    assert callable(getattr(m, f))\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_selected_cases_exist():
    if FIXTURES is None:
        pytest.skip("shared/ fixtures not found")
    have = set(fixture_cases())
    assert set(LAPLACIAN_CASES + SUBDIV_CASES) <= have


@requires_shared
@pytest.mark.parametrize("case", LAPLACIAN_CASES)
def test_laplacian_smooth_reproduces_fixture(br, case):
    c = load_fixture_case(case)
    p = dict(c["params"])
    p.pop("weights")
    weights = c.get("weights")
    assert (weights is not None) == (c["params"]["weights"] is not None)
    V, fs, fi = _mesh_arrays(c["mesh"])
    P, secs = br.laplacian_smooth(V, fs, fi, weights=weights, **p)
    assert P.shape == c["result"].shape and P.dtype == np.float64
    assert br.last_timing["what"] == "laplacian_smooth" and secs == statistics.median(br.last_timing["samples"])
    dev = np.abs(P - c["result"]).max() / _diag(c["result"])
    assert dev <= TOL, f"{case}: max deviation {dev:.3e} × diagonal"
    # the case actually moves the mesh
    assert np.abs(P - V).max() > 1e-4 * _diag(V)


@requires_shared
@pytest.mark.parametrize("case", SUBDIV_CASES)
def test_subdivision_reproduces_fixture(br, case):
    from scipy.spatial import cKDTree

    c = load_fixture_case(case)
    p = dict(c["params"])
    p.pop("weights")
    V, fs, fi = _mesh_arrays(c["mesh"])
    P, rfs, rfi, rw, secs = br.subdivision_surface(V, fs, fi, weights=c["weights"], **p)
    ref = c["result"]
    tol = TOL * _diag(ref)
    assert P.shape == ref.shape
    # original vertices come first (as in Blender); compare the rest as point sets
    d_ref, nn = cKDTree(P).query(ref)
    d_ours, _ = cKDTree(ref).query(P)
    assert d_ref.max() <= tol and d_ours.max() <= tol
    assert np.unique(nn).size == len(ref)  # a bijection
    assert rfs.sum() == rfi.size and np.array_equal(np.sort(rfs), np.sort(c["result_face_sizes"]))
    assert rw is not None and np.abs(rw[nn] - c["result_weights"]).max() <= 1e-6
    assert br.last_timing["what"] == "subdivision_surface" and secs == statistics.median(br.last_timing["samples"])


@requires_shared
def test_weights_without_vertex_group_change_nothing_when_all_one(br):
    # all-ones weights == no vertex group
    V, fs, fi = _mesh_arrays("torus")
    kw = dict(lambda_factor=-2.0, iterations=2)
    a, _ = br.laplacian_smooth(V, fs, fi, **kw)
    b, _ = br.laplacian_smooth(V, fs, fi, weights=np.ones(len(V)), **kw)
    c, _ = br.laplacian_smooth(V, fs, fi, weights=np.zeros(len(V)), **kw)
    assert np.array_equal(a, b)
    assert np.array_equal(c, V.astype(np.float32).astype(np.float64))


@requires_shared
def test_make_object_keeps_order_and_clear_scene_does_not_leak(br):
    import bpy

    V, fs, fi = _mesh_arrays("suzanne_hybrid")
    n_obj, n_mesh = len(bpy.data.objects), len(bpy.data.meshes)
    w = np.linspace(0.0, 1.0, len(V))
    ob = br.make_object(V, fs, fi, weights=w, name="t")
    me = ob.data
    co = np.empty(3 * len(V), np.float32)
    me.vertices.foreach_get("co", co)
    assert np.array_equal(co.reshape(-1, 3), V.astype(np.float32))
    corner = np.empty(len(fi), np.int32)
    me.loops.foreach_get("vertex_index", corner)
    assert np.array_equal(corner, fi)
    sizes = np.empty(len(fs), np.int32)
    me.polygons.foreach_get("loop_total", sizes)
    assert np.array_equal(sizes, fs)
    gi = ob.vertex_groups["weights"].index
    got = np.array([next(g.weight for g in me.vertices[i].groups if g.group == gi)
                    for i in (0, len(V) // 2, len(V) - 1)])
    assert np.allclose(got, w[[0, len(V) // 2, len(V) - 1]], atol=1e-7)
    br.clear_scene()
    for _ in range(3):
        br.laplacian_smooth(V, fs, fi, lambda_factor=0.5)
        br.subdivision_surface(V, fs, fi, weights=w)
    assert (len(bpy.data.objects), len(bpy.data.meshes)) == (n_obj, n_mesh)


def test_make_object_rejects_input_that_validate_would_alter(br):
    # a quad with a repeated vertex: Blender's validate() deletes it
    with pytest.raises(ValueError, match="validate"):
        br.make_object(np.eye(3), [4], [0, 1, 2, 1])
    # two copies of the same triangle: validate() drops one
    with pytest.raises(ValueError, match="validate"):
        br.make_object(np.vstack([np.eye(3), np.ones((1, 3))]), [3, 3], [0, 1, 2, 0, 1, 2])
    br.clear_scene()


@requires_shared
def test_timing_is_the_median_of_the_samples_and_keeps_the_baseline_apart(br):
    """The seconds returned are the median of the modifier's samples; the evaluation without the
    modifier is kept apart as ``baseline`` (its size is the benchmark's to report, not a test's)."""
    V, fs, fi = _mesh_arrays("suzanne_sub2")
    _, secs = br.laplacian_smooth(V, fs, fi, lambda_factor=1.0, repeat=3)
    t = br.last_timing
    assert t["what"] == "laplacian_smooth" and len(t["samples"]) == 3 and secs == sorted(t["samples"])[1]
    assert isinstance(t["baseline"], float) and t["baseline"] >= 0.0


def test_suzanne_sub4(br, tmp_path, monkeypatch):
    monkeypatch.setattr(br, "CACHE_DIR", Path(tmp_path))
    V, fs, fi = br.suzanne_sub4()
    assert V.shape == (126290, 3) and np.all(fs == 4) and fi.size == 4 * fs.size
    assert (tmp_path / "suzanne_sub4.npz").exists()
    V2, fs2, fi2 = br.suzanne_sub4()  # from the cache
    assert np.array_equal(V, V2) and np.array_equal(fi, fi2)
