"""One step's right-hand side and result (the flow family's ``step_rhs`` / ``step_result``): the
NumPy reference and the compiled twin give the bits the formulas give, signed zeros included."""

from __future__ import annotations

import numpy as np
import pytest

from shapeflow import accel

IMPLS = ["off", "force"]


def _family(mode: str):
    if mode == "force" and not accel.available():
        pytest.skip("numba (the 'fast' extra) not installed")
    with accel.use(kernels=mode):
        return accel.kernels("flow", 10)


def _case(seed: int = 4, n: int = 200):
    rng = np.random.default_rng(seed)
    V = rng.standard_normal((n, 3))
    V[4] = [-0.0, 0.0, -0.0]                                   # signed zeros: x + 0.0 turns −0.0 into +0.0
    X = V + 0.1 * rng.standard_normal((n, 3))
    c = rng.uniform(0.5, 2.0, n)
    held = np.array([0, 7, 3, 150], np.int64)
    c[held] = 0.0
    r = np.array([5, 9, 5, 3, 120, 5], np.int64)               # row 5 three times, row 3 held and coupled
    s = np.array([6, 10, 0, 8, 121, 199], np.int64)
    e = rng.uniform(0.1, 1.0, r.size)
    return V, X, c, held, r, s, e


def _expected_rhs(V, X, c, held, r, s, e):
    out = [[float(c[i] * V[i, k]) for k in range(3)] for i in range(V.shape[0])]
    for i in held:
        out[i] = [float(X[i, k]) for k in range(3)]
    if r.size:
        sums = {}
        for q in range(r.size):                                  # per row, in coupling order, from +0.0
            acc = sums.setdefault(int(r[q]), [0.0, 0.0, 0.0])
            for k in range(3):
                acc[k] = acc[k] + float(e[q] * X[s[q], k])
        for i in range(V.shape[0]):
            add = sums.get(i, [0.0, 0.0, 0.0])
            out[i] = [out[i][k] + add[k] for k in range(3)]
    return np.array(out)


@pytest.mark.parametrize("mode", IMPLS)
@pytest.mark.parametrize("coupled", [True, False])
def test_step_rhs_bits(mode, coupled):
    V, X, c, held, r, s, e = _case()
    if not coupled:
        r, s, e = r[:0], s[:0], e[:0]
    got = _family(mode).step_rhs(c, V, X, held, r, s, e)
    want = _expected_rhs(V, X, c, held, r, s, e)
    assert got.tobytes() == want.tobytes()
    assert np.signbit(got[4]).any() != coupled                # −0.0 kept without couplings only


@pytest.mark.parametrize("mode", IMPLS)
@pytest.mark.parametrize("how", ["plus", "flip", "per-row", "axes"])
def test_step_result_bits(mode, how):
    V, X, *_ = _case(7)
    X[11, 1] = np.nan
    X[12, 2] = np.inf
    factor = np.where(np.arange(V.shape[0]) % 3 == 0, -1.0, 1.0) if how == "per-row" else None
    flip = how == "flip"
    axes = np.array([True, False, True]) if how == "axes" else np.ones(3, bool)
    want = np.empty_like(V)
    for i in range(V.shape[0]):
        x = V[i] if not np.isfinite(X[i]).all() else X[i]
        f = factor[i] if factor is not None else (-1.0 if flip else 1.0)
        d = (x - V[i]) * f
        d[~axes] = 0.0
        want[i] = V[i] + d
    Xc = X.copy()
    out = np.empty_like(V)
    assert _family(mode).step_result(Xc, V, factor, flip, axes, out) == 2
    assert out.tobytes() == want.tobytes()
    assert _family(mode).step_result(Xc, V, factor, flip, axes, Xc) == 2     # in place
    assert Xc.tobytes() == want.tobytes()
