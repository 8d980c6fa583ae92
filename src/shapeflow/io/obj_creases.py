"""OpenSubdiv ``t crease`` tags of an OBJ file: a mesh's creases written as tags, and telling a
crease tag among the ``l``/``p``/``t`` lines the OBJ reader keeps."""

from __future__ import annotations

import numpy as np

__all__ = ["crease_tags", "is_crease_tag"]


def crease_tags(creases) -> list[tuple[str, str]]:
    """``mesh.creases`` (pairs, Blender's values c) as OBJ ``t crease 2/1 i j s`` lines: one per edge
    with a positive sharpness s = 10·c² (10: infinitely sharp), 0-based as OpenSubdiv reads them."""
    pairs, c = (np.asarray(x) for x in creases)
    s = np.minimum(10.0 * np.square(c.astype(np.float64)), 10.0)
    keep = s > 0
    if not keep.any():
        return []
    p = pairs[keep].astype(np.int64)
    rest = np.char.add(np.char.add(np.char.add("crease 2/1 ", p[:, 0].astype(str)), " "), p[:, 1].astype(str))
    rest = np.char.add(np.char.add(rest, " "), np.char.mod("%.17g", s[keep]))
    return [("t", r) for r in rest.tolist()]


def is_crease_tag(element) -> bool:
    """Whether an OBJ element line kept by the reader (tag, rest) is a ``t crease`` tag."""
    tag, rest = element
    return tag == "t" and rest.split()[:1] == ["crease"]
