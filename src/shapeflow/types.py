"""Type aliases of the public API (what each kind of argument accepts)."""

from __future__ import annotations

import os
from typing import Callable, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["ArrayLike", "PathLike", "Faces", "Weights", "Axes", "Falloff", "Color", "Size", "View"]

#: a file path: str or os.PathLike
PathLike = Union[str, "os.PathLike[str]"]
#: faces: a list of index lists (ragged), an (m, k) integer array, or None (no faces)
Faces = Union[Sequence[Sequence[int]], np.ndarray, None]
#: per-vertex weights in [0, 1]: None (all 1), a mesh attribute name, or an (n,) array
Weights = Union[None, str, ArrayLike]
#: coordinates that may change: three bools or a string such as "xz"
Axes = Union[Sequence[bool], str]
#: brush falloff: None (the paper: none), "smooth", or f(d/r) -> factors in [0, 1]
Falloff = Union[None, str, Callable[[np.ndarray], np.ndarray]]
#: a colour name, an RGB triple, a named field ("curvature", ...) or per-vertex/per-face values
Color = Union[str, Sequence[float], ArrayLike]
#: a picture size (width, height) in pixels
Size = Sequence[int]
#: a named view ("front", "iso", ...) or (azimuth, elevation) in degrees
View = Union[str, Sequence[float]]
