"""The studio's "Keep sharp edges": the family solved with it keeps a box's sides flat (and bends
them without it), the enhancement brush never drags a vertex off its face, the inflate brush holds
the vertices on sharp edges, the edges an OBJ file marks can be kept, and toggling is no edit."""

from __future__ import annotations

import numpy as np
import pytest
from meshgen import cube_sphere, random_rotation

import shapeflow as sf
from shapeflow.errors import ParameterError
from shapeflow.studio import StudioSession

HALF = np.array([1.5, 1.0, 0.7])          # the box's half extents
K = 6                                      # quads along each side of each face


def box_parts():
    """A box of 6 × K × K uneven quads with a bump on its top (z) side, rotated off the axes; for each
    of its six sides the vertices on it (by the unrotated coordinates), the top one last — the five
    others are flat, for a plane fit independent of shapeflow."""
    m = cube_sphere(K)
    unit = m.vertices / np.abs(m.vertices).max(axis=1, keepdims=True)     # back from the sphere to the cube
    sides = [np.flatnonzero(np.isclose(unit[:, a], s)) for a in range(3) for s in (-1.0, 1.0)]
    # an uneven grid: every coordinate not on a side moves by up to 0.3 of a quad (the sides stay flat)
    free = ~np.isclose(np.abs(unit), 1.0)
    unit = unit + free * np.random.default_rng(7).uniform(-0.3, 0.3, unit.shape) / K
    top = sides[5]
    unit[top, 2] += 0.3 * (1 - unit[top, 0] ** 2) * (1 - unit[top, 1] ** 2)     # 0 on the top's rim
    box = m.with_vertices((unit * HALF) @ random_rotation(3).T)
    return box, sides


def flatness(V, sides) -> float:
    """The largest distance of a vertex of the five flat sides from the least-squares plane of its side."""
    worst = 0.0
    for idx in sides[:5]:
        P = V[idx] - V[idx].mean(axis=0)
        normal = np.linalg.svd(P)[2][-1]
        worst = max(worst, float(np.abs(P @ normal).max()))
    return worst


@pytest.fixture
def parts():
    return box_parts()


def test_the_family_keeps_the_sides_flat_only_with_the_setting(parts):
    box, sides = parts
    diag = float(np.linalg.norm(2 * HALF))
    lams = [-120.0, -40.0, 0.0, 30.0]
    plain = StudioSession(box)
    plain.solve_family(lams, wait=True)
    kept = StudioSession(box)
    assert kept.set_features(True, 30.0) is True
    kept.solve_family(lams, wait=True)
    assert kept.family_status().state == "done"
    for lam in (-120.0, -40.0, -80.0):          # members, and a blend of two
        assert flatness(kept.shape_at(lam), sides) <= 1e-9 * diag
        assert flatness(plain.shape_at(lam), sides) > 1e-2 * diag
    # the corners stay where they are; the enhancement raised the bump
    corners = np.flatnonzero(sum(np.isin(np.arange(box.n_vertices), idx) for idx in sides) == 3)
    assert corners.size == 8
    assert np.allclose(kept.shape_at(-120.0)[corners], box.vertices[corners], atol=1e-12)
    assert np.linalg.norm(kept.shape_at(-120.0)[sides[5]] - box.vertices[sides[5]], axis=1).max() > 1e-2 * diag


def test_the_sharp_edges_are_the_boxs_twelve_edges(parts):
    box, sides = parts
    s = StudioSession(box)
    assert s.sharp_edges().shape == (0, 2)               # off: none
    s.set_features(True, 30.0)
    pairs = s.sharp_edges()
    # an edge of the box: both ends on two sides at once (a cube edge has K segments)
    on = np.zeros((box.n_vertices, 6), bool)
    for j, idx in enumerate(sides):
        on[idx, j] = True
    shared = (on[pairs[:, 0]] & on[pairs[:, 1]]).sum(axis=1)
    assert len(pairs) == 12 * K and (shared >= 1).all() and (on[pairs].sum(axis=2) >= 2).all()
    s.set_features(True, 95.0)                         # the box bends by 90°: nothing is sharper
    assert len(s.sharp_edges()) == 0


def test_toggling_is_not_an_edit(parts):
    box, _ = parts
    s = StudioSession(box)
    s.paint(box.vertices[0], 0.5, value=0.5)
    before = (s.version, s.can_undo, s.can_redo, s.modified, s.history_bytes, s.vertices, s.weights)
    assert s.set_features(True, 40.0) is True
    assert s.set_features(True, 40.0) is False         # the same setting: nothing to solve again
    assert s.set_features(False, 10.0) is True
    assert s.set_features(False, 70.0) is False        # off, whatever the angle
    after = (s.version, s.can_undo, s.can_redo, s.modified, s.history_bytes, s.vertices, s.weights)
    assert before[:5] == after[:5] and np.array_equal(before[5], after[5]) and np.array_equal(before[6], after[6])
    assert s.features == {"on": False, "angle": 70.0, "marked": False}
    s.undo()
    assert not s.can_undo and np.array_equal(s.weights, np.ones(box.n_vertices))


@pytest.mark.parametrize("bad", [{"angle": 180.5}, {"angle": -1}, {"angle": float("nan")}, {"angle": "30"},
                                 {"on": 1}, {"marked": "yes"}, {"marked": True}])
def test_a_bad_setting_is_refused_and_changes_nothing(parts, bad):
    s = StudioSession(parts[0])
    s.set_features(True, 45.0)
    args = {"on": True, "angle": 30.0, "marked": False, **bad}
    with pytest.raises(ParameterError):
        s.set_features(**args)                           # marked: this box marks no edge
    assert s.features == {"on": True, "angle": 45.0, "marked": False}


def test_the_enhancement_brush_never_drags_a_vertex_off_its_face(parts):
    box, sides = parts
    diag = float(np.linalg.norm(2 * HALF))
    # a dab on the bump next to the middle of its rim: the sphere holds vertices of the bump and of a flat side
    mid = np.intersect1d(sides[0], sides[5])
    inner = np.setdiff1d(sides[5], np.concatenate(sides[:5]))
    near = np.linalg.norm(box.vertices[inner] - box.vertices[mid[len(mid) // 2]], axis=1)
    centre = box.vertices[inner[np.argmin(near)]]
    results = {}
    for on in (False, True):
        s = StudioSession(box)
        s.set_features(on, 30.0)
        moved = s.dab(centre, radius=1.2, lam=-300.0)
        assert np.isin(moved, sides[0]).sum() >= 5            # it reached across the rim
        results[on] = s.vertices
        assert np.linalg.norm(s.vertices[sides[5]] - box.vertices[sides[5]], axis=1).max() > 1e-2 * diag
    assert flatness(results[True], sides) <= 1e-9 * diag
    assert flatness(results[False], sides) > 1e-3 * diag
    # the edge's vertices stay on the edge's line
    line = box.vertices[mid]
    d = (line[-1] - line[0]) / np.linalg.norm(line[-1] - line[0])
    off = results[True][mid] - line[0]
    assert np.abs(off - np.outer(off @ d, d)).max() <= 1e-9 * diag


def test_the_inflate_brush_holds_the_vertices_on_sharp_edges(parts):
    box, _ = parts
    s = StudioSession(box)
    s.set_features(True, 30.0)
    held = np.unique(s.sharp_edges())
    corner = box.vertices[held[0]]
    moved = s.dab(corner, radius=1.0, inflate=True, strength=0.2)
    assert moved.size > 10
    assert np.array_equal(s.vertices[held], box.vertices[held])
    assert not np.array_equal(s.vertices, box.vertices)
    s.set_features(False)                              # off: the next dab moves them too
    s.dab(corner, radius=1.0, inflate=True, strength=0.2)
    assert not np.array_equal(s.vertices[held], box.vertices[held])
    assert np.array_equal(s.weights, np.ones(box.n_vertices))       # the held vertices' weights are untouched


def obj_with_groups(box, sides, path):
    """The box as an OBJ file, each of its six sides a smoothing group of its own (s 1 … s 6)."""
    side = np.zeros(box.n_faces, int)
    F = [box.face_indices[box.face_offsets[f]:box.face_offsets[f + 1]] for f in range(box.n_faces)]
    for f, corners in enumerate(F):
        side[f] = next(j for j, idx in enumerate(sides) if np.isin(corners, idx).all())
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in box.vertices.tolist()]
    for j in range(6):
        lines.append(f"s {j + 1}")
        lines += ["f " + " ".join(str(i + 1) for i in F[f]) for f in np.flatnonzero(side == j)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_the_edges_an_obj_file_marks_can_be_kept(parts, tmp_path):
    box, sides = parts
    diag = float(np.linalg.norm(2 * HALF))
    s = StudioSession(sf.load(obj_with_groups(box, sides, tmp_path / "box.obj")))
    assert s.marked_count == 12 * K
    assert s.set_features(True, 180.0, marked=True)      # no edge by angle: only the file's marks
    pairs = {tuple(p) for p in np.sort(s.sharp_edges(), axis=1).tolist()}
    assert pairs == {tuple(p) for p in np.sort(s.marked_pairs, axis=1).tolist()}
    s.solve_family([-100.0, 0.0], wait=True)
    assert flatness(s.shape_at(-100.0), sides) <= 1e-9 * diag
    s.set_features(True, 180.0, marked=False)
    assert len(s.sharp_edges()) == 0
