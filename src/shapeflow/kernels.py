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

Switches: the environment variable ``SHAPEFLOW_KERNELS=0`` turns them off,
``SHAPEFLOW_KERNELS=force`` uses them at every size (tests);
:func:`enabled` does the same in code (``with kernels.enabled(False): ...``).

Memory pages: NumPy asks Linux for transparent huge pages (``madvise``) on
every array of 4 MB or more.  On the virtual machines we measure on, a
huge-page fault costs far more than the 512 small faults it replaces (the
2 MB come zeroed from memory the host has not backed yet): a fresh flow on
126K vertices spent ~60 ms in the kernel with huge pages and ~45 ms
without, on 937K vertices ~1.0 s against ~0.4 s.  So shapeflow's heavy
entry points (:func:`small_pages`) switch NumPy's hint off while they run
and restore it afterwards.  ``SHAPEFLOW_HUGE_PAGES=1`` keeps NumPy's
default (for machines where huge pages pay).

Examples
--------
>>> from shapeflow import kernels
>>> kernels.get(10) is None      # small problems never use them
True
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading

#: Smallest problem (vertices or unknowns) for which the kernels are used.
MIN_SIZE = 50_000

_ENV = os.environ.get("SHAPEFLOW_KERNELS", "1").strip().lower()
#: ``SHAPEFLOW_KERNELS=force`` uses the kernels at every size (the test suite runs that way in CI,
#: so the compiled paths are checked on the small meshes of the tests too)
_state = {"on": _ENV not in ("0", "false", "no", "off"), "force": _ENV == "force",
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
    if size < (MIN_SIZE if min_size is None else min_size) and not _state["force"]:
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


# --------------------------------------------------------------------------
# NumPy's transparent-huge-page hint, off while shapeflow's heavy code runs
# --------------------------------------------------------------------------

_pages = {"keep_huge": os.environ.get("SHAPEFLOW_HUGE_PAGES", "0").strip().lower() in ("1", "true", "yes", "on"),
          "depth": 0, "saved": None}
_pages_lock = threading.Lock()


def _madvise_setter():
    """NumPy's (private) switch of its huge-page hint, or None where it does not exist."""
    import numpy as np

    for mod in ("_core", "core"):
        try:
            f = getattr(getattr(np, mod).multiarray, "_set_madvise_hugepage")
        except AttributeError:
            continue
        return f
    return None


@contextlib.contextmanager
def small_pages():
    """Inside the block, NumPy allocates without asking for huge pages.

    Re-entrant and thread-safe: the first block to enter saves NumPy's
    setting, the last one to leave restores it.  The hint only changes how
    fast fresh memory arrives, never a result.  A no-op when
    ``SHAPEFLOW_HUGE_PAGES=1`` or when NumPy has no such switch.
    """
    setter = None if _pages["keep_huge"] else _madvise_setter()
    if setter is None:
        yield
        return
    with _pages_lock:
        if _pages["depth"] == 0:
            _pages["saved"] = setter(False)
        _pages["depth"] += 1
    try:
        yield
    finally:
        with _pages_lock:
            _pages["depth"] -= 1
            if _pages["depth"] == 0:
                setter(bool(_pages["saved"]))


def with_small_pages(fn):
    """Decorator: run ``fn`` inside :func:`small_pages`."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with small_pages():
            return fn(*args, **kwargs)
    return wrapper
