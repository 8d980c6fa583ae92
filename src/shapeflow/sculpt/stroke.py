"""Brush parameters and strokes: falloff functions, points, and a polyline resampled to dab centres."""

from __future__ import annotations

import math

import numpy as np

from .. import params
from ..errors import ParameterError

__all__ = ["FALLOFFS", "MAX_DABS", "positive", "smooth_falloff", "check_falloff", "apply_falloff", "as_point",
           "as_points", "resample_polyline"]


FALLOFFS = (None, "none", "constant", "smooth")


#: the most dabs one stroke is resampled to (a dab takes ~1-5 ms: about an hour of sculpting)
MAX_DABS = 1_000_000


def positive(name: str, x) -> float:
    return params.number(name, x, lo=0.0, lo_open=True)


def smooth_falloff(t: np.ndarray) -> np.ndarray:
    s = 1.0 - t * t
    return s * s


def check_falloff(falloff):
    if falloff is None or (isinstance(falloff, str) and falloff in ("none", "constant")):
        return None
    if isinstance(falloff, str):
        if falloff == "smooth":
            return smooth_falloff
        raise ParameterError(f"unknown falloff {falloff!r}; choose None, 'smooth' or a callable f(d/r)")
    if callable(falloff):
        return falloff
    raise ParameterError(f"falloff must be None, 'smooth' or a callable f(d/r), got {type(falloff).__name__}")


def apply_falloff(fn, t: np.ndarray) -> np.ndarray:
    f = np.asarray(fn(t), dtype=np.float64)
    if f.shape != t.shape:
        try:
            f = np.broadcast_to(f, t.shape).astype(np.float64)
        except ValueError:
            raise ParameterError(f"falloff returned shape {f.shape} for {t.shape[0]} distances") from None
    if not np.all(np.isfinite(f)) or (f.size and (f.min() < 0.0 or f.max() > 1.0)):
        raise ParameterError("falloff must return finite values in [0, 1]")
    return f


def as_point(center) -> np.ndarray:
    c = params.real_array("center", center).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ParameterError(f"a brush centre must be 3 finite numbers, got {np.asarray(center).tolist()!r}")
    return c


def as_points(points) -> np.ndarray:
    P = params.real_array("points", points)
    if P.ndim == 1 and P.size == 3:
        P = P.reshape(1, 3)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] == 0:
        raise ParameterError(f"stroke points must have shape (m, 3) with m >= 1, got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ParameterError("stroke points must be finite")
    return P.copy()


def resample_polyline(points, step: float) -> np.ndarray:
    """Points every ``step`` of arc length along a polyline, starting at its first point.

    The last point of the polyline is not added unless it falls on the grid;
    a single point gives itself.  ``step`` must be > 0.
    """
    P = as_points(points)
    step = positive("spacing", step)
    with np.errstate(over="ignore", invalid="ignore"):
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(cum[-1])
    if not math.isfinite(total):
        raise ParameterError("points: the stroke is too long to measure in double precision")
    if total == 0.0:
        return P[:1].copy()
    count = total / step + 1.0
    if count > MAX_DABS:
        raise ParameterError(f"spacing: a step of {step:.3g} along a stroke of length {total:.3g} gives "
                             f"{count:.3g} dabs; at most {MAX_DABS:,} (use a larger spacing)")
    s = np.arange(int(math.floor(total / step + 1e-9)) + 1) * step
    s = np.minimum(s, total)
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    # skip zero-length segments: searchsorted(side="right") already lands past them
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(seg[j] > 0, (s - cum[j]) / np.where(seg[j] > 0, seg[j], 1.0), 0.0)
    return P[j] + a[:, None] * (P[j + 1] - P[j])
