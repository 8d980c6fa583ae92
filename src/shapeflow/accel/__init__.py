"""The acceleration backend: which implementation of each kernel runs, from what size, and the memory-page policy.

One :class:`Backend` object holds every acceleration setting.  The one in
force is read with :func:`current`; :func:`use` changes it for a ``with``
block in the calling thread only (a :mod:`contextvars` variable, so other
threads and the caller's state are untouched); :func:`set_default` changes
the process default explicitly.  Nothing else in shapeflow changes
process-wide state.

Settings
--------
``kernels``
    ``"auto"`` (default): the compiled twins (the ``fast`` extra: numba) run
    on problems of at least ``min_size`` vertices or unknowns when numba is
    installed (the brush's kernel families, whose work is a dab's whatever the
    mesh, at every size); ``"off"``: NumPy/SciPy only; ``"force"``: compiled at every
    size (the test suite runs that way in CI, so the compiled paths are
    checked on small meshes too).  Every compiled kernel has a NumPy/SciPy
    twin computing the same formulas in the same order (the compiled CG's
    parallel sums differ only in rounding); the choice depends only on the
    size, so a given mesh always takes the same path.  Small meshes never pay
    numba's import (~0.5 s on first use in a process; compiled code is cached
    on disk after the first run).
``min_size``
    Smallest problem for the compiled kernels under ``"auto"`` (50,000).
``threads``
    Threads of the compiled parallel kernels: ``"auto"`` (default) takes the cores this process may
    use *now* — its CPU affinity and cgroup quota, less the other runnable tasks of the machine at
    the moment of the call (``/proc/loadavg``) — so a busy machine gets one thread instead of
    OpenMP workers waiting for a scheduler slice at every barrier; an integer fixes it.
    ``NUMBA_NUM_THREADS`` caps both.  The caller's own numba thread setting is restored after each
    call.  The count never changes a result: parallel sums are taken per fixed block of rows and
    added in block order.
``small_pages``
    Opt-in (default False).  NumPy asks Linux for transparent huge pages on
    every array of 4 MB or more.  On the virtual machines shapeflow is
    measured on, a huge-page fault costs more than the 512 small faults it
    replaces (the 2 MB come zeroed from memory the host has not backed yet):
    a fresh flow on 937K vertices spent ~1.0 s in the kernel with huge pages
    and ~0.4 s without (docs/performance.md).  With ``small_pages=True``
    shapeflow's heavy entry points switch NumPy's hint off while they run
    and restore it afterwards.  The hint is NumPy's process-wide setting, so
    while such a call runs, other threads of the process allocate without it
    too; that is why it is opt-in for the library.  The ``shapeflow``
    command turns it on for its own process.

Kernels
-------
Each package with hot loops defines a *kernel family* in ``<package>/kernels.py``: a class
whose methods are the NumPy/SciPy kernels.  :func:`kernels` gives the implementation that
runs a problem of a given size — the reference, or an accelerator's subclass
(:mod:`shapeflow.accel.registry`); callers call its methods and never branch on the backend.
The numba accelerator (:mod:`shapeflow.accel.numba_backend`) implements every family in the
package's ``compiled`` module.  Its kernels are
compiled on first use and cached on disk (``cache=True``).  Large arrays are
allocated by NumPy in the plain-Python wrappers (:func:`zeros`) and filled by
the compiled functions.  Indices read from arrays are cast to ``np.uint64``
before they index another array: numba tests every signed index for a
negative value, and these gathers are the inner loops (measured: CSR product
~15% faster, corner assembly ~25%).  Only indices that cannot be negative
are cast.

Processes
---------
A process forked (``os.fork``, ``multiprocessing``'s ``fork`` start method) after its parent ran
a parallel kernel on numba's OpenMP layer cannot start OpenMP threads: GNU OpenMP would end it.
shapeflow notices the fork and runs the NumPy/SciPy twins there, saying so once in a log line;
processes started with ``spawn`` or ``forkserver`` keep the compiled kernels.

Environment (read once, for the process default): ``SHAPEFLOW_KERNELS`` =
``0``/``off``, ``1``/``auto`` or ``force``; ``SHAPEFLOW_SMALL_PAGES=1``.

Examples
--------
>>> from shapeflow import accel
>>> accel.current().kernels in ("auto", "off", "force")
True
>>> with accel.use(kernels="off"):
...     accel.kernels("operators", 10**9).backend
'numpy'
>>> with accel.use(threads=1):          # one thread for the calls inside (the same results)
...     accel.thread_count()
1
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import functools
import logging
import os
import sys
import threading

from ..errors import ParameterError
from .registry import FAMILIES, Accelerator, Family, select

__all__ = ["Backend", "current", "use", "enabled", "set_default", "numba_available", "numba_usable", "available",
           "kernels", "Family", "Accelerator", "FAMILIES", "apply_call_threads", "sequential",
           "heavy", "small_pages", "zeros", "KERNEL_MODES", "thread_count", "usable_cores",
           "other_runnable"]

KERNEL_MODES = ("auto", "off", "force")

_log = logging.getLogger("shapeflow")


@dataclasses.dataclass(frozen=True)
class Backend:
    """Acceleration settings (immutable; see the module docstring for each)."""

    kernels: str = "auto"
    min_size: int = 50_000
    small_pages: bool = False
    threads: int | str = "auto"

    def __post_init__(self):
        if self.kernels not in KERNEL_MODES:
            raise ParameterError(f"kernels must be one of {', '.join(KERNEL_MODES)}, got {self.kernels!r}")
        if isinstance(self.min_size, bool) or not isinstance(self.min_size, int) or self.min_size < 0:
            raise ParameterError(f"min_size must be an integer >= 0, got {self.min_size!r}")
        if not isinstance(self.small_pages, bool):
            raise ParameterError(f"small_pages must be True or False, got {self.small_pages!r}")
        if self.threads != "auto" and (isinstance(self.threads, bool) or not isinstance(self.threads, int)
                                       or self.threads < 1):
            raise ParameterError(f"threads must be 'auto' or an integer >= 1, got {self.threads!r}")

    def uses_compiled(self, size: int, *, min_size: int | None = None) -> bool:
        """Whether a problem of ``size`` runs compiled (numba installed and the size reached)."""
        if self.kernels == "off":
            return False
        if self.kernels == "auto" and size < (self.min_size if min_size is None else min_size):
            return False
        return numba_usable()


def _from_environment() -> Backend:
    env = os.environ.get("SHAPEFLOW_KERNELS", "auto").strip().lower()
    mode = "off" if env in ("0", "false", "no", "off") else "force" if env == "force" else "auto"
    pages = os.environ.get("SHAPEFLOW_SMALL_PAGES", "0").strip().lower() in ("1", "true", "yes", "on")
    return Backend(kernels=mode, small_pages=pages)


_default = [_from_environment()]
_active: contextvars.ContextVar[Backend | None] = contextvars.ContextVar("shapeflow_backend", default=None)


def current() -> Backend:
    """The backend in force in this thread (the one of the innermost :func:`use`, else the default)."""
    b = _active.get()
    return _default[0] if b is None else b


@contextlib.contextmanager
def use(backend: Backend | None = None, **changes):
    """Run a ``with`` block under ``backend``, or the current one with ``changes``, in this thread only.

    >>> with use(kernels="off", min_size=0):
    ...     current().kernels
    'off'
    """
    b = dataclasses.replace(backend or current(), **changes)
    token = _active.set(b)
    try:
        yield b
    finally:
        _active.reset(token)


def enabled(on: bool):
    """``use(kernels="off")``, or the compiled kernels back on (keeping ``"force"`` if it is in force)."""
    mode = current().kernels
    return use(kernels=("force" if mode == "force" else "auto") if on else "off")


def set_default(backend: Backend | None = None, **changes) -> Backend:
    """Replace the process default (threads not inside :func:`use` see it); returns the old one."""
    old = _default[0]
    _default[0] = dataclasses.replace(backend or old, **changes)
    return old


@functools.cache
def numba_available() -> bool:
    """True when numba can be imported (the ``fast`` extra)."""
    try:
        import numba  # noqa: F401
    except Exception as exc:   # noqa: BLE001 - not installed, or broken (e.g. a NumPy it does not support)
        _log.info("shapeflow: compiled kernels unavailable (%s); NumPy/SciPy paths are used", exc)
        return False
    return True


def numba_usable() -> bool:
    """numba is installed and may start its threads in this process (see :func:`_forked_after_openmp`)."""
    return numba_available() and not _forked_after_openmp()


def available() -> bool:
    """True when numba is installed and the current backend does not switch the kernels off."""
    return current().kernels != "off" and numba_available()


# --------------------------------------------------------------------------
# fork: GNU OpenMP cannot run in a child forked after it ran in the parent
# --------------------------------------------------------------------------

_fork = {"after_openmp": False, "told": False}


def _after_fork_in_child() -> None:
    """In a child made by ``os.fork`` (``multiprocessing``'s default start method on Linux before
    Python 3.14): if the parent has run a parallel kernel on numba's OpenMP layer, a parallel
    kernel here would end the process (libgomp: "fork() called from a process already using GNU
    OpenMP") and leave a ``multiprocessing.Pool`` waiting for its result forever."""
    numba = sys.modules.get("numba")
    if numba is None:
        return
    try:
        layer = numba.threading_layer()
    except (ValueError, AttributeError):    # no parallel kernel has run: the child may start OpenMP itself
        return
    _fork["after_openmp"] = layer == "omp"
    _fork["told"] = False


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def _forked_after_openmp() -> bool:
    """Whether this process was forked after its parent ran OpenMP: its compiled kernels are off
    (the NumPy/SciPy twins run, same formulas) and a log line says so once."""
    if not _fork["after_openmp"]:
        return False
    if not _fork["told"]:
        _fork["told"] = True
        _log.warning("shapeflow: this process was forked after its parent ran numba's OpenMP threads, which "
                     "cannot run here; the NumPy/SciPy twins of the compiled kernels run instead (start "
                     "worker processes with the 'spawn' or 'forkserver' method to keep them)")
    return True


def kernels(family: str, size: int) -> Family:
    """The implementation of the kernel family ``family`` (:data:`FAMILIES`) that runs a problem of
    ``size`` vertices or unknowns under the current backend: an accelerator's when it is available
    and takes that size, else the NumPy/SciPy reference (see :mod:`shapeflow.accel.registry`)."""
    return select(family, size, current())


def sequential(kernel):
    """The sequential twin of a compiled parallel kernel: the same Python function compiled without
    ``parallel`` (its ``prange`` loops run as ``range``), cached on disk under its own name.

    A kernel runs it when the call has one thread and the twin measured faster than the parallel
    build on one thread: the Jacobi CG's product and updates (a CG solve of a step on Suzanne 126K
    triangulated 40 → 37 ms, medians of 25 interleaved rounds, 2026-11-24).  The edge sort's twin
    was not faster (13.1 vs 12.6 ms), so it has none.  Both builds compute the same sums in the
    same order, so they give the same bits (the twin keeps the kernel's ``fastmath`` and ``error_model``).
    """
    import types

    import numba

    f = kernel.py_func
    twin = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_sequential", f.__defaults__,
                              f.__closure__)
    # its own name: numba's disk cache keys a function by module and qualified name, not by options
    twin.__qualname__ = f.__qualname__ + "_sequential"
    twin.__module__ = f.__module__
    twin.__doc__ = f.__doc__
    opts = {k: v for k, v in kernel.targetoptions.items() if k in ("fastmath", "error_model")}
    return numba.njit(cache=True, **opts)(twin)


def zeros(shape, dtype=None):
    """``np.zeros`` as ``np.empty`` + fill: the pages are first touched by the calling thread,
    not by both threads of a parallel loop (concurrent page faults contend for the memory map)."""
    import numpy as np

    a = np.empty(shape, np.float64 if dtype is None else dtype)
    a.fill(0)
    return a


# --------------------------------------------------------------------------
# NumPy's transparent-huge-page hint (only with small_pages=True)
# --------------------------------------------------------------------------

_pages = {"depth": 0, "saved": None}
_pages_lock = threading.Lock()


@functools.cache
def madvise_setter():
    """NumPy's switch of its huge-page hint, or None where this NumPy has none."""
    import numpy as np

    for mod in ("_core", "core"):
        try:
            return getattr(getattr(np, mod).multiarray, "_set_madvise_hugepage")
        except AttributeError:
            continue
    return None


@contextlib.contextmanager
def small_pages():
    """Inside the block NumPy allocates without asking for huge pages (when the backend says so).

    A no-op unless ``current().small_pages``.  Re-entrant and thread-safe:
    the first block to enter saves NumPy's setting, the last one to leave
    restores it.  The hint changes how fast fresh memory arrives, never a
    result.
    """
    setter = madvise_setter() if current().small_pages else None
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


def usable_cores() -> int:
    """Cores this process may use: its CPU affinity, capped by its cgroup's CPU quota."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    try:
        with open("/proc/self/cgroup") as f:
            path = next((ln.split(":", 2)[2].strip() for ln in f if ln.startswith("0::")), None)
        if path is not None:
            with open(os.path.join("/sys/fs/cgroup", path.lstrip("/"), "cpu.max")) as f:
                quota, period = f.read().split()
            if quota != "max":
                cores = min(cores, max(1, int(int(quota) // int(period))))
    except (OSError, ValueError, StopIteration):
        pass
    return max(1, cores)


def other_runnable() -> int:
    """Tasks of the machine runnable right now besides the caller (``/proc/loadavg``; 0 elsewhere)."""
    try:
        with open("/proc/loadavg") as f:
            running = int(f.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return 0
    return max(0, running - 1)


def thread_count() -> int:
    """Threads the compiled parallel kernels use in a call starting now (see ``threads``)."""
    b = current()
    k = b.threads if b.threads != "auto" else max(1, usable_cores() - other_runnable())
    cap = os.environ.get("NUMBA_NUM_THREADS")
    if cap and cap.isdigit() and int(cap) >= 1:
        k = min(k, int(cap))
    return k


_call_threads: contextvars.ContextVar[int | None] = contextvars.ContextVar("shapeflow_threads", default=None)


def apply_call_threads() -> None:
    """Inside a heavy call, numba's thread count set to the call's (numba may have been imported
    since the call began); nothing outside one."""
    k = _call_threads.get()
    if k is not None:
        _apply_threads(k)


def _apply_threads(k: int) -> None:
    import numba

    numba.set_num_threads(max(1, min(k, numba.config.NUMBA_NUM_THREADS)))


def heavy(fn):
    """Decorator for shapeflow's heavy entry points: run ``fn`` inside :func:`small_pages`, with the
    thread count of :func:`thread_count` (the caller's numba setting restored afterwards)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if _call_threads.get() is not None:          # nested heavy call: the outer one decided
            return fn(*args, **kwargs)
        k = thread_count()
        token = _call_threads.set(k)
        numba = sys.modules.get("numba")
        old = numba.get_num_threads() if numba is not None else None
        if numba is not None:
            _apply_threads(k)
        try:
            with small_pages():
                return fn(*args, **kwargs)
        finally:
            _call_threads.reset(token)
            numba = sys.modules.get("numba")
            if numba is not None:   # back to the caller's setting (a fresh thread's default if numba was new)
                numba.set_num_threads(old if old is not None else numba.config.NUMBA_NUM_THREADS)
    return wrapper
