"""The studio's model: weights painted with a smooth falloff, brush dabs, the family of shapes
solved in the background, and one undo history over all of them."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from meshgen import cube_sphere

import shapeflow as sf
from shapeflow.studio import StudioSession


@pytest.fixture
def mesh():
    return cube_sphere(8, mix=0.3)          # quads and triangles, closed


def test_paint_follows_the_falloff_and_undoes_exactly(mesh):
    s = StudioSession(mesh)
    c, r = mesh.vertices[5], 0.6
    touched = s.paint(c, r, value=0.25, strength=0.8)
    d = np.linalg.norm(mesh.vertices - c, axis=1)
    inside = d < r
    assert set(touched.tolist()) == set(np.flatnonzero(inside).tolist())
    expected = np.ones(mesh.n_vertices)
    t = d[inside] / r
    expected[inside] = 1.0 + (0.25 - 1.0) * 0.8 * (1 - t ** 2) ** 2        # (1 − t²)², from its definition
    np.testing.assert_allclose(s.weights, expected, rtol=0, atol=1e-15)
    after = s.weights
    assert s.undo() and np.array_equal(s.weights, np.ones(mesh.n_vertices))
    assert s.redo() and np.array_equal(s.weights, after)                   # both ways exactly
    with pytest.raises(sf.ParameterError, match="radius"):
        s.paint(c, 0.0)
    with pytest.raises(sf.ParameterError, match="value"):
        s.paint(c, 0.5, value=2.0)


def test_dabs_use_the_painted_weights(mesh):
    s = StudioSession(mesh)
    c = mesh.vertices[5]
    s.paint(c, 0.5, value=0.0)                       # zero at the centre, rising towards the rim
    w = s.weights
    moved = s.dab(c, radius=0.7, lam=-40.0)
    ref = sf.Brush(mesh, radius=0.7, lam=-40.0, weights=w)
    ref_moved = ref.dab(c)
    assert set(moved.tolist()) == set(np.asarray(ref_moved).tolist())
    np.testing.assert_array_equal(s.vertices, ref.vertices)
    assert np.array_equal(s.vertices[w == 0.0], mesh.vertices[w == 0.0])   # weight 0: untouched
    before = s.vertices
    s.dab(c + 0.05, radius=0.7, lam=-40.0, inflate=True, strength=0.1)
    assert not np.array_equal(s.vertices, before)
    assert s.undo() and np.array_equal(s.vertices, before)
    assert s.undo() and np.array_equal(s.vertices, mesh.vertices)          # back to the input, exactly
    assert s.undo() and np.array_equal(s.weights, np.ones(mesh.n_vertices))
    assert not s.undo()


def test_family_in_the_background_and_its_blends(mesh):
    s = StudioSession(mesh)
    s.paint(mesh.vertices[0], 0.8, value=0.3)
    w = s.weights
    s.solve_family([0.0, -10.0, -20.0, -40.0])
    deadline = time.monotonic() + 60
    while s.family_status().state == "running" and time.monotonic() < deadline:
        time.sleep(0.01)
    st = s.family_status()
    assert st.state == "done" and st.done == st.total == 4 and st.lams == [-40.0, -20.0, -10.0, 0.0]
    for lam in (-10.0, -40.0):                      # members: the flow itself, to the CG tolerance
        ref = sf.flow(mesh, lam, weights=w).vertices
        assert np.abs(s.shape_at(lam) - ref).max() <= 1e-6 * np.abs(ref - mesh.vertices).max()
    np.testing.assert_allclose(s.shape_at(-15.0), 0.5 * (s.shape_at(-10.0) + s.shape_at(-20.0)), atol=1e-15)
    np.testing.assert_array_equal(s.shape_at(-100.0), s.shape_at(-40.0))     # clamped to the range
    s.apply_shape(-15.0)
    np.testing.assert_array_equal(s.vertices, s.shape_at(-15.0))
    assert s.undo() and np.array_equal(s.vertices, mesh.vertices)


def test_a_new_solve_supersedes_and_failures_are_reported(mesh):
    s = StudioSession(mesh)
    with pytest.raises(sf.ParameterError, match="no family"):
        s.shape_at(-1.0)
    s.solve_family([0.0, -5.0])
    s.solve_family([0.0, -7.0], wait=True)          # the first one's result is dropped
    time.sleep(0.2)
    assert s.family_status().lams == [-7.0, 0.0]
    s.solve_family([-1.0], wait=True, strategy="no such strategy")
    st = s.family_status()
    assert st.state == "failed" and "strategy" in st.error


def test_history_length_files_and_threads(mesh, tmp_path):
    s = StudioSession(mesh, undo_steps=2)
    for k in range(4):
        s.paint(mesh.vertices[k * 7], 0.5, value=0.0)
    assert s.undo() and s.undo() and not s.undo()
    s.paint(mesh.vertices[3], 0.5, value=0.5)
    s.save(tmp_path / "painted.ply")
    back = StudioSession.open(tmp_path / "painted.ply")
    np.testing.assert_array_equal(back.weights, s.weights)
    # several threads painting at once: every stroke lands, each as one step
    t = StudioSession(mesh, undo_steps=100)
    threads = [threading.Thread(target=lambda k=k: [t.paint(mesh.vertices[(k * 13 + j) % mesh.n_vertices], 0.3,
                                                             value=0.0) for j in range(5)]) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert t.version == 20
    undone = 0
    while t.undo():
        undone += 1
    assert undone == 20 and np.array_equal(t.weights, np.ones(mesh.n_vertices))


def test_colour_fields_on_a_sphere():
    from meshgen import icosphere

    ball = icosphere(3, r=2.0)
    s = StudioSession(ball)
    h = s.field("curvature")
    assert abs(np.median(h) - 0.5) < 0.02 and h.min() > 0.4            # H = 1/r on a sphere
    assert np.array_equal(s.field("displacement"), np.zeros(ball.n_vertices))
    s.solve_family([0.0, -30.0], wait=True)
    s.apply_shape(-30.0)                              # enhancing a sphere mostly inflates it
    d = s.field("displacement")
    grown = np.linalg.norm(s.vertices, axis=1) - 2.0
    np.testing.assert_allclose(d, grown, rtol=0.05, atol=1e-3 * 2.0)   # along the normal: radial here
    assert np.array_equal(s.field("weights"), np.ones(ball.n_vertices))
    with pytest.raises(sf.ParameterError, match="unknown field"):
        s.field("colour")


def test_painting_between_dabs_reuses_the_brush_with_the_new_weights(mesh):
    s = StudioSession(mesh)
    c = mesh.vertices[5]
    ref = sf.Brush(mesh, radius=0.7, lam=-40.0)
    s.dab(c, radius=0.7, lam=-40.0)
    ref.dab(c)
    s.paint(c, 0.4, value=0.0)
    ref.set_weights(s.weights)
    s.dab(c + 0.02, radius=0.7, lam=-40.0)
    ref.dab(c + 0.02)
    np.testing.assert_array_equal(s.vertices, ref.vertices)
    fresh = sf.Brush(sf.Mesh.from_csr(ref.vertices, mesh.face_sizes, mesh.face_indices), radius=0.7, lam=-40.0,
                     weights=s.weights)
    assert np.array_equal(ref.weights, fresh.weights)
    with pytest.raises(sf.ParameterError, match="weights"):
        ref.set_weights(np.full(mesh.n_vertices, 2.0))


def test_weights_from_a_file_are_one_undo_step(mesh):
    s = StudioSession(mesh)
    s.paint(mesh.vertices[0], 0.5, value=0.0)
    w = np.linspace(0.0, 1.0, mesh.n_vertices)
    s.set_weights(w)
    np.testing.assert_array_equal(s.weights, w)
    assert s.undo() and s.weights[0] == 0.0 and not np.array_equal(s.weights, w)    # back to the painted ones
    assert s.redo() and np.array_equal(s.weights, w)
    with pytest.raises(sf.ParameterError, match="shape"):
        s.set_weights(w[:-1])
    with pytest.raises(sf.ParameterError, match=r"\[0, 1\]"):
        s.set_weights(w * 2.0)
    with pytest.raises(sf.ParameterError, match="None"):
        s.set_weights(None)
    np.testing.assert_array_equal(s.weights, w)                   # refused weights change nothing


def test_fields_of_the_previewed_shape(mesh):
    s = StudioSession(mesh)
    s.solve_family([0.0, -10.0, -20.0], wait=True)
    shape = s.shape_at(-15.0)                                     # a blend between two members
    H = sf.mean_curvature(mesh.with_vertices(shape), area="barycentric")
    np.testing.assert_array_equal(s.field("curvature", lam=-15.0), H)
    from shapeflow.geometry.normals import vertex_normals

    n = vertex_normals(mesh)
    np.testing.assert_allclose(s.field("displacement", lam=-15.0), ((shape - mesh.vertices) * n).sum(axis=1),
                               rtol=0, atol=1e-14)
    assert np.abs(s.field("displacement")).max() == 0.0          # the current shape is still the input
    np.testing.assert_array_equal(s.input_vertices, mesh.vertices)


def test_field_scale_is_the_98th_percentile():
    from shapeflow.studio.server import field_scale

    values = np.linspace(-3.0, 1.0, 1001)                         # |v| sorted: 0 … 3, 1001 values
    a = np.sort(np.abs(values))
    assert field_scale(values) == a[int(0.98 * 1000)]
    assert field_scale(np.zeros(10)) == 1.0 and field_scale(np.zeros(0)) == 1.0
