"""Hard-surface meshes for the command line's sharp-feature tests, built here with NumPy alone.

* :func:`quad_box`: a box of k × k quads on each side (every face a quad), its vertex sets: the
  six sides (each in a plane), the twelve box edges (each on a line), the eight corners;
* :func:`box_obj`: the box as OBJ text, optionally with one smoothing group per side
  (``s 1`` … ``s 6``) and ``t crease`` tags on the box edges;
* :func:`l_bracket`: the machined L-bracket with a fillet of tests/flow/feature_shapes.py.

Which vertices lie on a plane or a line comes from the construction, not from shapeflow.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location(
    "feature_shapes", Path(__file__).resolve().parents[1] / "flow" / "feature_shapes.py")
feature_shapes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(feature_shapes)

plane_dev, line_dev = feature_shapes.plane_dev, feature_shapes.line_dev
EXACT = 1e-9        # × the bounding-box diagonal


def quad_box(k: int = 3, size=(2.0, 1.0, 1.0)):
    """(V, sides, info): vertices, the quads of each side (outward), and the vertex sets of the
    sides ("sides"), box edges ("edges") and corners ("corners")."""
    S = np.asarray(size, float)
    g = np.linspace(0.0, 1.0, k + 1)
    grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    on_surface = (np.isclose(grid, 0.0) | np.isclose(grid, 1.0)).any(axis=1)
    V = grid[on_surface] * S
    number = {tuple(np.round(p / S * k).astype(int)): i for i, p in enumerate(V)}
    sides = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for hi in (0, k):
            quads = []
            for i in range(k):
                for j in range(k):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        c = [0, 0, 0]
                        c[axis], c[u], c[v] = hi, i + di, j + dj
                        quad.append(number[tuple(c)])
                    p = V[quad]
                    normal = np.cross(p[1] - p[0], p[2] - p[0])
                    outward = np.zeros(3)
                    outward[axis] = 1.0 if hi else -1.0
                    quads.append(quad if normal @ outward > 0 else quad[::-1])
            sides.append(quads)
    return V, sides, box_sets(V, size)


def box_sets(V, size=(2.0, 1.0, 1.0)) -> dict:
    """The vertices of ``V`` on each side of the box (by position), on each of its twelve edges, at its corners."""
    S = np.asarray(size, float)
    extreme = np.isclose(V, 0.0) | np.isclose(V, S)
    info = {"sides": [np.flatnonzero(np.isclose(V[:, a], x)) for a in range(3) for x in (0.0, S[a])],
            "edges": [], "corners": np.flatnonzero(extreme.sum(axis=1) == 3)}
    for a in range(3):                       # the four box edges along axis a
        b, c = [x for x in range(3) if x != a]
        for xb in (0.0, S[b]):
            for xc in (0.0, S[c]):
                info["edges"].append(np.flatnonzero(np.isclose(V[:, b], xb) & np.isclose(V[:, c], xc)))
    return info


def box_edge_pairs(V, sides, size=(2.0, 1.0, 1.0)) -> np.ndarray:
    """The mesh edges that lie on the box's edges (both ends on two of its planes), sorted pairs."""
    S = np.asarray(size, float)
    extreme = np.isclose(V, 0.0) | np.isclose(V, S)
    pairs = set()
    for q in (q for side in sides for q in side):
        for a, b in zip(q, q[1:] + q[:1]):
            if (extreme[a] & extreme[b]).sum() >= 2:
                pairs.add((min(a, b), max(a, b)))
    return np.array(sorted(pairs), np.int64)


def box_obj(V, sides, *, groups: bool = False, creases=None) -> str:
    """OBJ text of the box: ``groups``: one smoothing group per side; ``creases``: (pairs, sharpness)
    written as ``t crease 2/1 i j s`` tags (0-based, OpenSubdiv's convention)."""
    out = [f"v {x!r} {y!r} {z!r}" for x, y, z in V.tolist()]
    for s, quads in enumerate(sides):
        if groups:
            out.append(f"s {s + 1}")
        out += ["f " + " ".join(str(i + 1) for i in q) for q in quads]
    if creases is not None:
        pairs, sharpness = creases
        out += [f"t crease 2/1 {a} {b} {s!r}" for (a, b), s in zip(pairs.tolist(), np.broadcast_to(
            np.asarray(sharpness, float), len(pairs)).tolist())]
    return "\n".join(out) + "\n"


def l_bracket():
    """The L-bracket (flat walls and caps, straight edges, five corners, a round fillet) and its
    vertex sets (tests/flow/feature_shapes.py)."""
    return feature_shapes.l_bracket(split=0.2, seed=3)


def flatness(V, info) -> float:
    """The largest deviation of a flat side (or cap) from its plane and of a straight edge from its line."""
    planes = list(info.get("caps", [])) + list(info["sides"])
    return max(max(plane_dev(V[g]) for g in planes), max(line_dev(V[g]) for g in info["edges"]))
