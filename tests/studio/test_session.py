"""The studio's model: weights painted with a smooth falloff, brush dabs, the family of shapes
solved in the background, and one undo history over all of them."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from meshgen import cube_sphere
from stroke_reference import blended

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
    ref = sf.Brush(mesh, radius=0.7, lam=-40.0, weights=w, falloff="smooth")     # one dab: the brush's own
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


def test_history_is_bounded_in_bytes_files_and_threads(mesh, tmp_path):
    centres = [mesh.vertices[k * 7] for k in range(4)]
    inside = [np.flatnonzero(np.linalg.norm(mesh.vertices - c, axis=1) < 0.5) for c in centres]
    # a paint step keeps its indices (int64) and the weights before and after (float64); no positions
    sizes = [24 * len(i) for i in inside]
    s = StudioSession(mesh, history_bytes=sizes[2] + sizes[3])
    for c in centres:
        s.paint(c, 0.5, value=0.0)
    assert s.history_bytes == (sizes[2] + sizes[3], sizes[2] + sizes[3])     # the two oldest were dropped
    assert s.undo() and s.undo() and not s.undo()
    s.paint(mesh.vertices[3], 0.5, value=0.5)
    s.save(tmp_path / "painted.ply")
    back = StudioSession.open(tmp_path / "painted.ply")
    np.testing.assert_array_equal(back.weights, s.weights)
    # several threads painting at once: every paint lands, each as one step
    t = StudioSession(mesh)
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


def test_a_stroke_is_one_step_holding_the_union_of_its_dabs(mesh):
    s = StudioSession(mesh)
    path = [mesh.vertices[5] + t * (mesh.vertices[40] - mesh.vertices[5]) for t in np.linspace(0.0, 1.0, 6)]
    s.begin_stroke()
    moved = [s.dab(c, radius=0.5, lam=-30.0) for c in path]
    assert s.in_stroke and s.can_undo and s.modified
    assert s.end_stroke() and not s.in_stroke and not s.end_stroke()
    np.testing.assert_allclose(s.vertices, blended(mesh, path, 0.5, -30.0), rtol=0, atol=1e-14)
    union = np.unique(np.concatenate(moved))
    assert len(union) > max(len(m) for m in moved)           # the dabs touched different vertices
    # one step: the union's indices (int64) and positions before and after (float64 × 3); no weights
    assert s.history_bytes[0] == len(union) * (8 + 24 + 24)
    after = s.vertices
    assert s.undo() and np.array_equal(s.vertices, mesh.vertices) and not s.can_undo    # the first 'before'
    assert s.redo() and np.array_equal(s.vertices, after)                               # the last 'after'


def test_a_dangling_stroke_ends_at_the_next_other_edit(mesh):
    s = StudioSession(mesh)
    s.begin_stroke()
    s.dab(mesh.vertices[5], radius=0.5, lam=-30.0)
    s.paint(mesh.vertices[9], 0.4, value=0.0)
    stroked_V, stroked_w = s.vertices, s.weights
    s.set_weights(np.full(mesh.n_vertices, 0.5))              # not a stroke's edit: the stroke ends first
    assert not s.in_stroke
    assert s.undo() and np.array_equal(s.weights, stroked_w) and np.array_equal(s.vertices, stroked_V)
    assert s.undo() and np.array_equal(s.vertices, mesh.vertices) and np.all(s.weights == 1.0)
    assert not s.undo()
    s.begin_stroke()                                          # undo ends an open stroke as well
    s.dab(mesh.vertices[5], radius=0.5, lam=-30.0)
    assert s.undo() and np.array_equal(s.vertices, mesh.vertices) and not s.in_stroke


def test_modified_counts_from_the_state_saved(mesh):
    s = StudioSession(mesh)
    assert not s.modified
    s.paint(mesh.vertices[0], 0.5, value=0.0)
    assert s.modified
    assert s.undo() and not s.modified                        # back to the state as opened
    assert s.redo() and s.modified
    saved, mark = s.saved_mesh()
    s.mark_saved(mark)
    assert not s.modified and np.array_equal(saved.weights, s.weights)
    assert s.undo() and s.modified and s.redo() and not s.modified
    s.paint(mesh.vertices[9], 0.5, value=0.0)
    assert s.modified
    one = 24 * int((np.linalg.norm(mesh.vertices - mesh.vertices[9], axis=1) < 0.5).sum())
    t = StudioSession(mesh, history_bytes=one)               # room for one step: the state as opened is lost
    t.paint(mesh.vertices[0], 0.5, value=0.0)
    t.paint(mesh.vertices[9], 0.5, value=0.0)
    assert t.undo() and not t.undo() and t.modified           # it is not the state as opened


def test_mirrored_dabs_follow_the_view_rule_and_are_one_step():
    spot = sf.load_example("spot")                            # faces -z, y up: the side axis is x
    s = StudioSession(spot)
    lo, hi = spot.vertices.min(axis=0), spot.vertices.max(axis=0)
    cx = 0.5 * (lo[0] + hi[0])
    np.testing.assert_allclose(s.mirrored([cx + 0.3, 0.1, 0.2]), [cx - 0.3, 0.1, 0.2], atol=1e-15)
    turned = sf.Mesh.from_csr(spot.vertices, spot.face_sizes, spot.face_indices, metadata={"front": "+x"})
    t = StudioSession(turned)                                 # faces +x: the side axis is z
    cz = 0.5 * (lo[2] + hi[2])
    np.testing.assert_allclose(t.mirrored([0.1, 0.2, cz + 0.25]), [0.1, 0.2, cz - 0.25], atol=1e-15)
    c = spot.vertices[np.argmax(spot.vertices[:, 0])]          # far from the plane
    m = c * [-1.0, 1.0, 1.0] + [2 * cx, 0.0, 0.0]
    s.dab(c, radius=0.2, lam=-40.0, mirror=True)
    np.testing.assert_allclose(s.vertices, blended(spot, [c, m], 0.2, -40.0), rtol=0, atol=1e-14)
    assert s.undo() and np.array_equal(s.vertices, spot.vertices) and not s.can_undo
    on_plane = spot.vertices[np.argmin(np.abs(spot.vertices[:, 0] - cx) + 10 * (spot.vertices[:, 1] < 0.2))]
    single = sf.Brush(spot, radius=0.2, lam=-40.0, falloff="smooth")
    single.dab(on_plane)
    s.dab(on_plane, radius=0.2, lam=-40.0, mirror=True)       # on the plane: one dab, not two
    np.testing.assert_array_equal(s.vertices, single.vertices)
    u = StudioSession(spot)
    touched = u.paint(c, 0.2, value=0.0, mirror=True)
    d = np.minimum(np.linalg.norm(spot.vertices - c, axis=1), np.linalg.norm(spot.vertices - m, axis=1))
    assert set(touched.tolist()) == set(np.flatnonzero(d < 0.2).tolist())
    assert u.undo() and np.all(u.weights == 1.0) and not u.can_undo


def test_paint_measures_on_the_positions_given_and_previews_survive_weights(mesh):
    s = StudioSession(mesh)
    s.solve_family([0.0, -30.0], wait=True)
    assert s.can_preview
    shown = s.shape_at(-30.0)
    c = shown[12]
    touched = s.paint(c, 0.3, value=0.0, on=shown)
    assert set(touched.tolist()) == set(np.flatnonzero(np.linalg.norm(shown - c, axis=1) < 0.3).tolist())
    assert s.can_preview                                      # the positions did not change
    s.dab(mesh.vertices[5], radius=0.5, lam=-30.0)
    assert not s.can_preview                                  # they did


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
    """Lone dabs (no stroke open) apply one after the other, on the library's brush kept between them."""
    s = StudioSession(mesh)
    c = mesh.vertices[5]
    ref = sf.Brush(mesh, radius=0.7, lam=-40.0, falloff="smooth")
    s.dab(c, radius=0.7, lam=-40.0)
    ref.dab(c)
    s.paint(c, 0.4, value=0.0)
    ref.set_weights(s.weights)
    s.dab(c + 0.02, radius=0.7, lam=-40.0)               # on the shape the first dab left, the new weights
    ref.dab(c + 0.02)
    np.testing.assert_array_equal(s.vertices, ref.vertices)
    fresh = sf.Brush(sf.Mesh.from_csr(ref.vertices, mesh.face_sizes, mesh.face_indices), radius=0.7, lam=-40.0,
                     weights=s.weights)
    assert np.array_equal(ref.weights, fresh.weights)
    with pytest.raises(sf.ParameterError, match="weights"):
        ref.set_weights(np.full(mesh.n_vertices, 2.0))


def test_the_dabs_of_a_stroke_do_not_compound(mesh):
    """One implicit step at λ −300 nearly doubles the surface's deviation from the membrane its rim spans;
    six dabs at one place applied one after the other move it 2^5 = 32 times as far.  In a stroke they
    blend: six dabs at one place are one dab, and a stroke moves no vertex further than the farthest
    its dabs move it alone."""
    c = mesh.vertices[5]
    one = sf.Brush(mesh, radius=0.6, lam=-300.0, falloff="smooth")
    one.dab(c)
    s = StudioSession(mesh)
    s.begin_stroke()
    for _ in range(6):
        s.dab(c, radius=0.6, lam=-300.0)
    s.end_stroke()
    np.testing.assert_allclose(s.vertices, one.vertices, rtol=0, atol=1e-14)
    seq = sf.Brush(mesh, radius=0.6, lam=-300.0, falloff="smooth")
    for _ in range(6):
        seq.dab(c)
    far = lambda V: np.linalg.norm(V - mesh.vertices, axis=1).max()          # noqa: E731
    assert far(seq.vertices) > 8 * far(one.vertices)                       # what compounding does
    path = [mesh.vertices[5] + t * (mesh.vertices[40] - mesh.vertices[5]) for t in np.linspace(0.0, 1.0, 8)]
    alone = []
    for p in path:
        b = sf.Brush(mesh, radius=0.6, lam=-300.0, falloff="smooth")
        b.dab(p)
        alone.append(np.linalg.norm(b.vertices - mesh.vertices, axis=1))
    t = StudioSession(mesh)
    t.begin_stroke()
    for p in path:
        t.dab(p, radius=0.6, lam=-300.0)
    t.end_stroke()
    moved = np.linalg.norm(t.vertices - mesh.vertices, axis=1)
    assert moved.max() > 0 and np.all(moved <= np.max(alone, axis=0) + 1e-12)


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
