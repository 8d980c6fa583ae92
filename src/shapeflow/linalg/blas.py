"""BLAS thread control for small dense factorisations, and the record of fast paths not taken.

:class:`SingleThreadBLAS` runs LAPACK on one thread (the OpenBLAS in SciPy's
wheels threads small blocked updates, which slows small banded solves);
:func:`split_routines` gives the raw LAPACK/BLAS pointers of the two-thread
split solver.  When either is unavailable the caller falls back to a slower
path; every such fallback is recorded once in :data:`FALLBACKS` and logged
(INFO, logger ``"shapeflow"``), never silent.
"""

from __future__ import annotations

import functools
import logging

__all__ = ["FALLBACKS", "note_fallback", "loaded_openblas", "SingleThreadBLAS", "split_routines"]


#: why an optional fast path is not used in this process (key -> reason); each is logged once
FALLBACKS: dict[str, str] = {}


_log = logging.getLogger("shapeflow")


def note_fallback(key: str, reason: str) -> None:
    """Record (and log once, at INFO on the "shapeflow" logger) that a fast path falls back."""
    if key not in FALLBACKS:
        FALLBACKS[key] = reason
        _log.info("shapeflow: %s", reason)


def loaded_openblas() -> list[str]:
    """Paths of the OpenBLAS that SciPy's wheels ship (``scipy.libs/``, not NumPy's) when this process
    has already loaded it (Linux: read from ``/proc/self/maps``; elsewhere none, and LAPACK keeps its
    threads, recorded in :data:`FALLBACKS`)."""
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f
                     if "libscipy_openblas" in line and "/scipy.libs/" in line}
    except OSError:
        return []
    return sorted(paths)


class SingleThreadBLAS:
    """Run LAPACK's banded Cholesky on one thread.

    OpenBLAS threads the small blocked updates inside ``dpbtrf``; on the 2-core
    reference machine that made a 2,600-unknown solve 2–5× slower (median)
    than one thread, much worse when other jobs share the machine.  Uses the
    thread-local setter of the OpenBLAS bundled with SciPy wheels when it is
    there (cheap, affects this thread only), else ``threadpoolctl`` when it
    is installed, else nothing.
    """

    _how = None         # "local" | "threadpoolctl" | "" (not available)
    _setter = None
    _controller = None

    @classmethod
    def _find(cls) -> str:
        if cls._how is not None:
            return cls._how
        cls._how = ""
        try:
            import ctypes

            import scipy.linalg  # noqa: F401  (loads SciPy's OpenBLAS)

            for path in loaded_openblas():
                lib = ctypes.CDLL(path)   # already in the process: a new handle, nothing loaded
                if hasattr(lib, "openblas_set_num_threads_local"):
                    f = lib.openblas_set_num_threads_local
                    f.argtypes = [ctypes.c_int]
                    f.restype = ctypes.c_int
                    cls._setter = f
                    cls._how = "local"
                    return cls._how
        except Exception as exc:  # pragma: no cover - platform dependent
            note_fallback("blas-local",
                          f"OpenBLAS's thread-local setter could not be loaded ({type(exc).__name__}: {exc})")
        try:  # pragma: no cover - depends on what is installed
            from threadpoolctl import ThreadpoolController

            cls._controller = ThreadpoolController()
            cls._how = "threadpoolctl"
        except Exception as exc:
            note_fallback("blas", "LAPACK's banded Cholesky may use several OpenBLAS threads: no thread-local setter "
                              f"and no threadpoolctl ({type(exc).__name__})")
        return cls._how

    def __enter__(self):
        how = self._find()
        self._old = None
        self._limiter = None
        if how == "local":
            self._old = self._setter(1)
        elif how == "threadpoolctl":  # pragma: no cover
            self._limiter = self._controller.limit(limits=1, user_api="blas")
        return self

    def __exit__(self, *exc):
        if self._old is not None:
            self._setter(self._old)
        elif self._limiter is not None:  # pragma: no cover
            self._limiter.restore_original_limits()
        return False


@functools.cache
def split_routines():
    """ctypes pointers to the LAPACK/BLAS routines of the split solver (SciPy's
    ``cython_lapack``/``cython_blas``) and OpenBLAS's thread-local thread count
    setter, or None where any is missing (the one-band solver is used then)."""
    if SingleThreadBLAS._find() != "local":
        note_fallback("split", "the two-thread split solver needs the thread-local setter of the OpenBLAS in SciPy's "
                           "wheels; dabs use one band")
        return None
    try:
        import ctypes

        from numba.extending import get_cython_function_address

        vp = ctypes.c_void_p
        fns = []
        for mod, name, nargs in (("lapack", "dpbtrf", 6), ("lapack", "dtbtrs", 11), ("lapack", "dpotrf", 5),
                                 ("lapack", "dpotrs", 8), ("blas", "dtrsm", 11), ("blas", "dsyrk", 10),
                                 ("blas", "dgemm", 13)):
            addr = get_cython_function_address("scipy.linalg.cython_" + mod, name)
            fns.append(ctypes.CFUNCTYPE(None, *([vp] * nargs))(addr))
        addr = ctypes.cast(SingleThreadBLAS._setter, vp).value
        fns.append(ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_int)(addr))
    except Exception as exc:  # pragma: no cover - depends on the SciPy build
        note_fallback("split", f"SciPy's LAPACK/BLAS pointers are not available ({type(exc).__name__}: {exc}); "
                           "dabs use one band")
        return None
    return tuple(fns)
