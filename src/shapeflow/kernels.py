"""Optional compiled kernels for large meshes (the ``fast`` extra: numba).

``pip install 'shapeflow[fast]'`` makes the hot paths — edge derivation, the
operator's sparse pattern, cotangent assembly and the conjugate-gradient
solve — run as compiled loops (CG on both cores).  Without numba everything
runs on NumPy/SciPy, with the same results: the kernels compute the same
formulas in the same order (the CG's parallel sums differ only in rounding),
and the test suite runs both paths against each other.

The kernels are used for problems of at least :data:`MIN_SIZE` vertices, so
that small meshes never pay numba's import (~0.5 s on first use in a
process; compiled code is cached on disk after the very first run).  The
choice depends only on the size, so a given mesh always takes the same path.

Switches: the environment variable ``SHAPEFLOW_KERNELS=0`` turns them off;
:func:`enabled` does the same in code (``with kernels.enabled(False): ...``).

Examples
--------
>>> from shapeflow import kernels
>>> kernels.get(10) is None      # small problems never use them
True
"""

from __future__ import annotations

import contextlib
import os

#: Smallest problem (vertices or unknowns) for which the kernels are used.
MIN_SIZE = 50_000

_state = {"on": os.environ.get("SHAPEFLOW_KERNELS", "1").strip().lower() not in ("0", "false", "no", "off"),
          "module": None, "tried": False}


def available() -> bool:
    """True when numba is installed and the kernels are switched on."""
    return _load() is not None


def _load():
    if not _state["on"]:
        return None
    if not _state["tried"]:
        _state["tried"] = True
        try:
            from . import _numba_kernels
        except ImportError:
            _state["module"] = None
        else:
            _state["module"] = _numba_kernels
    return _state["module"]


def get(size: int, *, min_size: int | None = None):
    """The kernels module when available and ``size`` >= ``min_size`` (default :data:`MIN_SIZE`), else None."""
    if size < (MIN_SIZE if min_size is None else min_size):
        return None
    return _load()


@contextlib.contextmanager
def enabled(on: bool):
    """Switch the kernels on or off inside a ``with`` block (tests, benchmarks)."""
    old = _state["on"]
    _state["on"] = bool(on)
    try:
        yield
    finally:
        _state["on"] = old
