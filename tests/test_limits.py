"""Work that cannot fit is refused before it starts, with the estimate in the message."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import need

import shapeflow as sf
from shapeflow import budget
from shapeflow.errors import ParameterError


def test_available_memory_is_known_here():
    room = budget.available_bytes()
    assert room is None or room > 0


@pytest.mark.parametrize("call,match", [
    (lambda m: sf.subdivide(m, levels=12), r"levels: 12 levels of subdivision \(2,928 faces -> 49,123,688,448 quads\) "
                                           r"needs about [0-9.]+ TB"),
    (lambda m: sf.subdivision_matrix(m, levels=12), "levels: 12 levels"),
    (lambda m: sf.subdivision_matrix(m.topology, levels=20), "levels: 20 levels"),
    (lambda m: sf.flow(m, 1.0, iterations=10 ** 9), "iterations must be <= 100000"),
])
def test_oversized_requests_are_refused(call, match):
    with pytest.raises(ParameterError, match=match):
        call(sf.load_example("spot"))


def test_the_estimates_follow_the_memory_there_is(monkeypatch):
    mesh = sf.load_example("spot")
    # level 2 of Spot: 11,712 corners -> 46,848 quads at ~500 bytes: ~23 MB
    monkeypatch.setattr(budget, "available_bytes", lambda: 10_000_000)
    with pytest.raises(ParameterError, match=r"46,848 quads\) needs about 23.4 MB of memory; "
                                             r"this machine has 10 MB available"):
        sf.subdivide(mesh, 2)
    with pytest.raises(ParameterError, match=r"lams: a family of 400 members of 2,930 vertices"):
        sf.family(mesh, np.linspace(0.0, -100.0, 400))
    monkeypatch.setattr(budget, "available_bytes", lambda: None)     # unknown: no refusal
    assert sf.subdivide(mesh, 2).n_faces == 46_848


def test_absurd_levels_are_refused_without_overflow():
    with pytest.raises(ParameterError, match="more than 1e120 quads"):
        sf.subdivide(sf.load_example("spot"), levels=10 ** 20)


def test_a_step_too_small_to_move_anything_says_so():
    out = sf.flow(sf.load_example("spot"), 1e-320)
    assert out.report.max_displacement == 0.0
    assert any("moves nothing representable" in n for n in out.report.notes)


def test_render_grid_with_empty_rows_is_refused():
    need("vtk", "VTK (the 'render' extra)")
    from shapeflow.rendering.api import grid_shape as _grid

    assert _grid((1, 2), 2) == (1, 2) and _grid((2, 2), 3) == (2, 2)
    with pytest.raises(ParameterError, match="empty"):
        _grid((100_000, 100_000), 2)


def test_long_work_reports_progress():
    mesh = sf.load_example("spot")
    seen = []
    sf.subdivide(mesh, 2, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 2), (2, 2)]
    seen.clear()
    sf.Brush(mesh, lam=-10.0, radius=0.1).stroke(mesh.vertices[:4], spacing=None,
                                                  progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    seen.clear()
    sf.flow(mesh, -5.0, iterations=3, update="recompute", progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 3), (2, 3), (3, 3)]
