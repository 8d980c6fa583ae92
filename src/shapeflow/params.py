"""Validation of the public API's scalar parameters.

Every check raises :class:`~shapeflow.errors.ParameterError` (a ``ValueError``)
naming the parameter, so no ``TypeError``, ``OverflowError`` or
``ZeroDivisionError`` escapes from bad input.  Booleans, strings and bytes are
not numbers; a number is not a boolean.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .errors import ParameterError

__all__ = ["LAMBDA_MAX", "number", "real_array", "lam", "flag", "integer", "progress", "rtol", "axes"]

#: The largest |λ| (and |λ_b|) the flow accepts.  The scaled system's diagonal
#: term is m/|λ|: past ~1e15 it vanishes against the Laplacian in double
#: precision and the system is singular.  At 1e12 one step is already its
#: limit (smoothing: the weighted mean of every free part; enhancement: its
#: reflection) to about 1e-12/μ₂ of the displacement, μ₂ the smallest non-zero
#: eigenvalue of the normalised Laplacian.
LAMBDA_MAX = 1e12


def number(name: str, x, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False) -> float:
    """A finite real number (Python or NumPy), optionally within [lo, hi] (or (lo, hi] with ``lo_open``)."""
    if isinstance(x, (bool, np.bool_, str, bytes)) or not isinstance(x, (numbers.Real, np.ndarray)) \
            or (isinstance(x, np.ndarray) and (x.ndim != 0 or x.dtype.kind not in "iuf")):
        raise ParameterError(f"{name} must be a number, got {x!r}")
    try:
        v = float(x)
    except OverflowError:
        raise ParameterError(f"{name} must be finite, got a number too large for double precision") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {v}")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise ParameterError(f"{name} must be {'>' if lo_open else '>='} {lo:g}, got {v:g}")
    if hi is not None and v > hi:
        raise ParameterError(f"{name} must be <= {hi:g}, got {v:g}")
    return v


def real_array(name: str, x) -> np.ndarray:
    """``x`` as a float64 array, refusing strings, bytes, booleans, complex and integers beyond double range.

    Only the element types are checked here; shapes and finiteness are the caller's.
    """
    try:
        a = np.asarray(x)
        if a.dtype.kind == "O":   # mixed or huge Python numbers: each must be a real number
            flat = a.reshape(-1)
            if any(isinstance(v, (bool, np.bool_, str, bytes)) or not isinstance(v, numbers.Real) for v in flat):
                raise TypeError
            a = a.astype(np.float64)
        elif a.dtype.kind not in "iuf":
            raise TypeError
        return a.astype(np.float64, copy=False)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{name} must be real numbers, got {_short(x)}") from None


def _short(x) -> str:
    r = repr(x)
    return r if len(r) <= 80 else r[:77] + "..."


def lam(name: str, x) -> float:
    """A flow factor λ: finite, |λ| <= :data:`LAMBDA_MAX`."""
    v = number(name, x)
    if abs(v) > LAMBDA_MAX:
        raise ParameterError(f"|{name}| must be <= {LAMBDA_MAX:g} (beyond it the flow's system is singular in "
                             f"double precision, and one step is its limit already), got {v:g}")
    return v


def flag(name: str, x) -> bool:
    """A boolean: ``True``/``False`` (Python or NumPy) only; 0, 1, "no" are refused."""
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    raise ParameterError(f"{name} must be True or False, got {x!r}")


def integer(name: str, x, *, lo: int = 0, hi: int | None = None) -> int:
    """An integer (not a bool) within [lo, hi]."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (numbers.Integral, np.integer)):
        raise ParameterError(f"{name} must be an integer, got {x!r}")
    v = int(x)
    if v < lo:
        raise ParameterError(f"{name} must be >= {lo}, got {v}")
    if hi is not None and v > hi:
        raise ParameterError(f"{name} must be <= {hi}, got {v}")
    return v


def progress(x):
    """A progress callback: None or a callable(done, total)."""
    if x is not None and not callable(x):
        raise ParameterError(f"progress must be a callable(done, total) or None, got {x!r}")
    return x


def rtol(x) -> float:
    """A solver tolerance in (0, 1)."""
    v = number("rtol", x, lo=0.0, lo_open=True)
    if v >= 1.0:
        raise ParameterError(f"rtol must be < 1, got {v:g}")
    return v


def axes(x) -> np.ndarray:
    """Which coordinates may move: three booleans (or 0/1) or a string of letters from 'xyz'."""
    if isinstance(x, str):
        bad = set(x.lower()) - set("xyz")
        if bad:
            raise ParameterError(f"axes must be letters from 'xyz', got {x!r}")
        return np.array([c in x.lower() for c in "xyz"])
    if isinstance(x, bytes):
        raise ParameterError(f"axes must be three booleans or a string like 'xz', got {x!r}")
    try:
        items = list(x)
    except TypeError:
        raise ParameterError(f"axes must be three booleans or a string like 'xz', got {x!r}") from None
    if len(items) != 3:
        raise ParameterError(f"axes must have three entries (x, y, z), got {len(items)}")
    out = []
    for i, a in enumerate(items):
        if not (isinstance(a, (bool, np.bool_))
                or (isinstance(a, (numbers.Integral, np.integer)) and int(a) in (0, 1))):
            raise ParameterError(f"axes[{i}] must be True/False (or 0/1), got {a!r}")
        out.append(bool(a))
    return np.array(out)
