"""Memory a solve reuses instead of asking for new: buffers no longer needed whose pages are in memory
already (the first touch of fresh memory, the operating system zeroing its pages, is a large share of
a family's time on one thread: on Suzanne ×4, 47–64 ms of system time per family with these buffers,
79–420 ms without; docs/performance.md, "The family's shared solve").

:class:`Spare` hands out (rows, width) arrays from such buffers first fit, new memory once none has
room; :func:`factor_memory` the zeroed factors of a multi-shift solve and, right after them,
``extra`` values of scratch for their powers, in its receiver's ``scratch``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Spare", "factor_memory"]


class Spare:
    """Flat float64 buffers (1-D, C-contiguous) handed out as (rows, width) C-contiguous arrays, first
    fit, each part once; :meth:`take` returns new memory when no buffer has room.  Not thread-safe:
    one solve's own bookkeeping."""

    def __init__(self, buffers=()):
        self.free = [[b, 0] for b in (buffers or ()) if b is not None]

    def take(self, rows: int, width: int) -> np.ndarray:
        size = rows * width
        for slot in self.free:
            b, o = slot
            if o + size <= b.size:
                slot[1] = o + size
                return b[o:o + size].reshape(rows, width)
        return np.empty((rows, width))


def factor_memory(n: int, ranks: list, emit, extra: int = 0) -> tuple[list, np.ndarray | None]:
    """Zeroed (n, r) vertex-major arrays for the factors of the given ranks (None: none), and a flat
    buffer of ``extra`` values after them (None without ``extra``), in ``emit.scratch``'s buffer where it
    offers one (see :func:`~shapeflow.linalg.multishift.multishift_cg`), else new."""
    size = sum(n * r for r in ranks if r is not None)
    flat = getattr(emit, "scratch", lambda size: None)(size + extra)
    spare = Spare([flat])
    out = []
    for r in ranks:
        if r is None:
            out.append(None)
            continue
        out.append(spare.take(n, r))
        out[-1].fill(0.0)
    return out, (spare.take(1, extra).reshape(-1) if extra else None)
