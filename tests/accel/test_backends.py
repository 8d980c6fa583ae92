"""The seam between shapeflow's algorithms and its kernels: ``accel.kernels(family, size)``.

* every family has its NumPy/SciPy reference and its numba implementation, a subclass that adds
  no kernel of its own (callers see one interface);
* the choice follows the settings exactly (``SHAPEFLOW_KERNELS`` off / auto / force, ``min_size``,
  families of small problems from any size);
* an accelerator is one module: a test accelerator defined here, implementing one kernel as a
  plain class, runs in the flow when it is available and takes the size, and nowhere else;
* the reference twins of kernels the NumPy path never runs (the lean layout, the permuted
  gathers) against the numba ones.
"""

from __future__ import annotations

import inspect

import meshgen
import numpy as np
import pytest

import shapeflow as sf
from shapeflow import accel
from shapeflow.accel import registry

needs_numba = pytest.mark.skipif(not accel.numba_available(), reason="numba (the 'fast' extra) not installed")


def _public_methods(cls) -> set[str]:
    return {m for m, f in inspect.getmembers(cls, inspect.isfunction) if not m.startswith("_")}


@pytest.mark.parametrize("family", list(registry.FAMILIES))
def test_every_family_has_a_reference(family):
    ref = registry.reference(family)
    assert isinstance(ref, accel.Family) and ref.family == family and ref.backend == "numpy"
    assert _public_methods(type(ref)), family
    with accel.use(kernels="off"):
        assert accel.kernels(family, 10**9) is ref


@needs_numba
@pytest.mark.parametrize("family", list(registry.FAMILIES))
def test_the_numba_implementation_is_the_family_compiled(family):
    ref = type(registry.reference(family))
    with accel.use(kernels="force"):
        impl = accel.kernels(family, 1)
    assert impl.backend == "numba" and isinstance(impl, ref)
    assert _public_methods(type(impl)) <= _public_methods(ref)            # no kernel outside the family
    overridden = {m for m in _public_methods(type(impl)) if getattr(type(impl), m) is not getattr(ref, m)}
    assert overridden, f"the numba {family} family overrides no kernel"
    for m in overridden:                                                  # same parameters as the reference
        assert list(inspect.signature(getattr(type(impl), m)).parameters) == \
            list(inspect.signature(getattr(ref, m)).parameters), (family, m)


@needs_numba
def test_the_choice_follows_the_settings():
    small = accel.current().min_size
    with accel.use(kernels="auto"):
        assert accel.kernels("flow", small - 1).backend == "numpy"
        assert accel.kernels("flow", small).backend == "numba"
        assert accel.kernels("sculpt", 1).backend == "numba"            # a dab is small whatever the mesh
        assert accel.kernels("local", 1).backend == "numba"
        with accel.use(min_size=10):
            assert accel.kernels("mesh", 9).backend == "numpy" and accel.kernels("mesh", 10).backend == "numba"
        with accel.enabled(False):
            assert {accel.kernels(f, 10**9).backend for f in registry.FAMILIES} == {"numpy"}
        with accel.enabled(True):
            assert accel.kernels("flow", small).backend == "numba"
    with accel.use(kernels="force"):
        assert {accel.kernels(f, 0).backend for f in registry.FAMILIES} == {"numba"}
        with accel.enabled(True):                                         # keeps "force"
            assert accel.kernels("mesh", 0).backend == "numba"
    with accel.use(kernels="off"):
        assert accel.kernels("sculpt", 10**9).backend == "numpy"
    with pytest.raises(ValueError, match="no kernel family 'cuda'"):
        accel.kernels("cuda", 1)


# --- a test accelerator: one module (this one), one kernel, as a GPU backend would be --------------

CALLS: list[str] = []
AVAILABLE = [True]


class TestFlow:
    """The test accelerator's flow kernels: one, delegating to the reference (so results must not change)."""

    __test__ = False

    def max_row_distance(self, A, B, chunk=4096):
        CALLS.append("max_row_distance")
        return super().max_row_distance(A, B, chunk)


TEST_ACCELERATOR = accel.Accelerator(name="test", available=lambda: AVAILABLE[0],
                                     families={"flow": f"{__name__}:TestFlow"}, min_size=100)


@pytest.fixture
def with_test_accelerator(monkeypatch):
    monkeypatch.setattr(registry, "ACCELERATORS", (f"{__name__}:TEST_ACCELERATOR", *registry.ACCELERATORS))
    CALLS.clear()
    AVAILABLE[0] = True
    yield
    AVAILABLE[0] = True


def test_an_accelerator_is_one_module(with_test_accelerator):
    m = meshgen.grid(12, 10, jitter=0.2, seed=1, z=lambda x, y: 0.1 * x * y)      # 143 vertices
    with accel.use(kernels="off"):
        ref = sf.flow(m, -3.0)
    assert CALLS == []
    with accel.use(kernels="auto", min_size=10**9):
        impl = accel.kernels("flow", m.n_vertices)
        assert impl.backend == "test" and isinstance(impl, type(registry.reference("flow")))
        assert accel.kernels("flow", 99).backend == "numpy"               # below the accelerator's own size
        assert accel.kernels("mesh", m.n_vertices).backend == "numpy"     # a family it does not implement
        out = sf.flow(m, -3.0)
    assert CALLS == ["max_row_distance"]                                  # the flow ran the test kernel
    np.testing.assert_array_equal(out.vertices, ref.vertices)
    AVAILABLE[0] = False                                                  # e.g. no GPU in this process
    with accel.use(kernels="force"):
        assert accel.kernels("flow", m.n_vertices).backend == ("numba" if accel.numba_available() else "numpy")


# --- reference twins the NumPy path does not run ------------------------------------------------------------

@needs_numba
def test_the_lean_layout_twins():
    m = meshgen.cube_sphere(6, mix=0.4, seed=3)
    fs = sf.FlowSolver(m, weights=np.where(np.arange(m.n_vertices) % 4 == 0, 0.0, 1.0))
    op = fs.operator()
    free = ~op.boundary & ~op.locked & (fs.systems.w > 0)
    c = np.where(free, op.mass / 3.0, 0.0)
    with accel.use(kernels="force"):
        fast = accel.kernels("flow", 1)
    ref = registry.reference("flow")
    pairs = op.pattern.pairs
    d1, mixed1, r1 = fast.interior_diag(pairs, free, c, op.deg, op.pw)
    d0, mixed0, r0 = ref.interior_diag(pairs, free, c, op.deg, op.pw)
    assert np.array_equal(d1, d0) and mixed1 == mixed0 and r1 == r0 and sum(mixed0) > 0
    A0, diag0, none, ratio0 = ref.interior_matrix(op.pattern, free, c, op.deg, op.pw)
    assert none is None and np.array_equal(diag0, d0) and ratio0 == r0
    listed = ref.interior_coupling(pairs, free, op.pw, None)
    for x, y in zip(fast.interior_coupling(pairs, free, op.pw, mixed1), listed):
        assert np.array_equal(x, y)


@needs_numba
def test_the_permuted_gathers_twins():
    rng = np.random.default_rng(2)
    n = 1000
    V = rng.standard_normal((n, 3))
    V[::7] = np.inf                                  # held rows: never read
    free = np.isfinite(V[:, 0])
    perm = rng.permutation(n)
    inv = np.empty(n, np.int64)
    inv[perm] = np.arange(n)
    with accel.use(kernels="force"):
        fast = accel.kernels("flow", 1)
    ref = registry.reference("flow")
    for a in (V[:, 1].copy(), V):
        assert np.array_equal(fast.take(a, perm.astype(np.int32)), ref.take(a, perm.astype(np.int32)))
        assert np.array_equal(ref.take(a, perm), a[perm])
    out1, out0 = np.empty((n, 3)), np.empty((n, 3))
    fast.take_free(V, perm, free, out1)
    ref.take_free(V, perm, free, out0)
    assert np.array_equal(out1, out0) and np.isfinite(out0).all() and (out0[~free[perm]] == 0).all()
    Y = rng.standard_normal((n, 3))
    fast.untake_free(Y, inv, free, V, out1)
    ref.untake_free(Y, inv, free, V, out0)
    assert np.array_equal(out1, out0, equal_nan=True)
    assert np.array_equal(out0[free], Y[inv][free]) and np.isinf(out0[~free]).all()
