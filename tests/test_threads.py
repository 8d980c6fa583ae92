"""Stateful objects shared between threads: serialised (Brush), or safe to run at once (FlowSolver)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import shapeflow as sf


def _hammer(target, n_threads=4):
    errors = []

    def run(seed):
        try:
            target(seed)
        except BaseException as exc:   # noqa: BLE001 - any escape is the failure this test looks for
            errors.append(repr(exc))

    threads = [threading.Thread(target=run, args=(s,)) for s in range(n_threads)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert not any(t.is_alive() for t in threads)
    return errors


@pytest.mark.parametrize("kind", ["Brush", "InflateBrush"])
def test_one_brush_from_four_threads(kind):
    mesh = sf.load_example("spot")
    brush = sf.Brush(mesh, lam=-50.0, radius=0.3) if kind == "Brush" else \
        sf.InflateBrush(mesh, strength=0.05, radius=0.3)
    brush.undo_limit = 10_000
    steps = []

    def work(seed):
        rng = np.random.default_rng(seed)
        for _ in range(60):
            r = rng.random()
            if r < 0.1:
                brush.undo()
            elif r < 0.15:
                brush.redo()
            elif r < 0.25:
                brush.stroke(mesh.vertices[rng.integers(mesh.n_vertices, size=3)])
            else:
                brush.dab(mesh.vertices[rng.integers(mesh.n_vertices)])
            steps.append(brush.mesh.n_vertices)

    assert _hammer(work) == []
    assert np.isfinite(brush.vertices).all()
    # whatever the interleaving, the history is consistent: undoing everything gives the input exactly
    while brush.can_undo:
        brush.undo()
    assert np.array_equal(brush.vertices, mesh.vertices)


def test_flow_solver_runs_from_threads_equal_serial_runs():
    mesh = sf.load_example("spot")
    lams = [-5.0, 3.0, -20.0, 8.0]
    serial = [sf.FlowSolver(mesh).run(lam, iterations=2).vertices for lam in lams]
    solver = sf.FlowSolver(mesh)
    got = {}

    def work(i):
        got[i] = solver.run(lams[i], iterations=2).vertices

    assert _hammer(work) == []
    for i in range(4):
        assert np.array_equal(got[i], serial[i])
