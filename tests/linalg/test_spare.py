"""linalg.spare: buffers handed out first fit, each part once, new memory when none has room."""

from __future__ import annotations

import numpy as np

from shapeflow.linalg.spare import Spare, factor_memory


def test_spare_hands_out_parts_first_fit_then_new_memory():
    a, b = np.zeros(10), np.zeros(25)
    sp = Spare([a, None, b])
    x = sp.take(2, 4)                   # a[0:8]
    y = sp.take(3, 5)                   # not in a (2 left): b[0:15]
    z = sp.take(1, 2)                   # a[8:10]
    w = sp.take(2, 6)                   # no room anywhere (b has 10 left): new
    assert x.shape == (2, 4) and x.flags.c_contiguous and np.shares_memory(x, a)
    assert np.shares_memory(y, b) and np.shares_memory(z, a) and not np.shares_memory(z, x)
    assert not np.shares_memory(w, a) and not np.shares_memory(w, b)
    x[:] = 1.0
    y[:] = 2.0
    z[:] = 3.0
    assert np.array_equal(a, np.r_[np.ones(8), 3.0, 3.0]) and np.array_equal(b, np.r_[np.full(15, 2.0), np.zeros(10)])


def test_factor_memory_is_zeroed_in_the_receivers_scratch_or_new():
    buf = np.full(100, np.nan)

    class Receiver:
        def scratch(self, size):
            return buf[:size] if size <= buf.size else None

    got, extra = factor_memory(10, [3, None, 4], Receiver())
    assert got[1] is None and [g.shape for g in (got[0], got[2])] == [(10, 3), (10, 4)] and extra is None
    assert all(np.shares_memory(g, buf) and not g.any() for g in (got[0], got[2]))
    assert np.isnan(buf[70:]).all()
    got, extra = factor_memory(10, [3, 4], Receiver(), extra=25)      # the extra values right after
    assert extra.shape == (25,) and np.shares_memory(extra, buf[70:95]) and np.isnan(buf[95:]).all()
    new, extra = factor_memory(10, [6, 5], Receiver(), extra=5)       # 115 values: the scratch is too small
    assert all(not np.shares_memory(g, buf) and not g.any() for g in new) and extra.shape == (5,)
    assert [g.shape for g in factor_memory(4, [2], object())[0]] == [(4, 2)]
