"""Machined shapes for the feature-aware flow's tests: prisms with flat faces, straight and round feature
lines and corners, built here with NumPy alone (independent of shapeflow's code but ``sf.Mesh``).

Every shape is an extruded profile (a closed polygon in the xy-plane, counter-clockwise), from
z = 0 to z = ``height``: flat caps meshed by rings (a triangle fan at the centre, quads outside; or
quads between an outer and an inner loop for a hole), walls of quads in ``layers`` rows.  The
helpers return the mesh and the vertex sets the tests check: caps, each straight wall, each
straight feature line, the corners.
"""

from __future__ import annotations

import numpy as np

import shapeflow as sf


def plane_dev(P) -> float:
    """Largest distance of the points P from their best-fit plane (SVD)."""
    c = P.mean(axis=0)
    return float(np.abs((P - c) @ np.linalg.svd(P - c)[2][2]).max())


def line_dev(P) -> float:
    """Largest distance of the points P from their best-fit line (SVD)."""
    c = P.mean(axis=0)
    d = P - c
    u = np.linalg.svd(d)[2][0]
    return float(np.linalg.norm(d - np.outer(d @ u, u), axis=1).max())


def polyline(corners, per_side: int) -> np.ndarray:
    """A closed polygon through ``corners`` with ``per_side`` segments per side (no repeated point)."""
    c = np.asarray(corners, float)
    t = np.arange(per_side)[:, None] / per_side
    return np.concatenate([c[k] + t * (c[(k + 1) % len(c)] - c[k]) for k in range(len(c))])


def arc(center, radius, a0, a1, segments: int, endpoint: bool = False) -> np.ndarray:
    a = np.linspace(a0, a1, segments + 1)[:(None if endpoint else -1)]
    return np.c_[center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)]


def _orient(V, faces, expected):
    """Flip the faces whose vector area points against ``expected`` (one direction per face)."""
    out = []
    for f, e in zip(faces, expected):
        p = V[f]
        area = 0.5 * np.cross(p - p[0], np.roll(p, -1, axis=0) - p[0]).sum(axis=0)
        out.append(list(f) if area @ e >= 0 else list(f[::-1]))
    return out


def _collinear(loop, j):
    """Whether points j, j+1, j+2 of a closed loop lie on one line."""
    n = len(loop)
    a, b, c = loop[j % n], loop[(j + 1) % n], loop[(j + 2) % n]
    return abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) < 1e-12


def extrusion(outer, corners, *, inner=None, center=(0.0, 0.0), rings: int = 3, layers: int = 3,
              height: float = 1.0, split: float = 0.0, hexagons: int = 0, seed: int = 0):
    """An extruded profile as a closed mesh; ``inner``: a hole (as many points as ``outer``).

    ``corners``: the profile's corners (points of ``outer`` where it turns); the straight sides
    run between consecutive corners.  ``split``: chance to cut a wall quad into two triangles;
    ``hexagons``: how many pairs of wall quads on a straight side become one hexagon.  Returns
    ``(mesh, info)``: info["caps"] (vertex ids of each cap), info["sides"] (vertex ids of each flat
    wall), info["edges"] (vertex ids of each vertical corner line and each cap outline side),
    info["corners"] (the profile corners at both caps), info["hole"] (the hole's wall, rims included).
    """
    rng = np.random.default_rng(seed)
    outer = np.asarray(outer, float)
    N = len(outer)
    c = np.asarray(center, float)
    start = c[None, :] if inner is None else np.asarray(inner, float)
    ring_pts = [start + (i / rings) * (outer - start) for i in range(0 if inner is not None else 1, rings + 1)]
    R = len(ring_pts) - 1                               # the outer loop's ring number
    V, idx = [], {}

    def add(key, p):
        idx[key] = len(V)
        V.append(p)

    for zi, z in enumerate((0.0, height)):
        if inner is None:
            add(("c", zi), [c[0], c[1], z])
        for r, pts in enumerate(ring_pts):
            for j in range(N):
                add(("r", zi, r, j), [pts[j, 0], pts[j, 1], z])
    for k in range(1, layers):                          # wall layers between the caps
        for j in range(N):
            add(("o", k, j), [outer[j, 0], outer[j, 1], height * k / layers])
            if inner is not None:
                add(("i", k, j), [inner[j, 0], inner[j, 1], height * k / layers])
    V = np.array(V)

    def wall(kind, k, j):
        if k in (0, layers):
            return idx[("r", k // layers, R if kind == "o" else 0, j % N)]
        return idx[(kind, k, j % N)]

    faces, expect = [], []
    for zi, nz in ((0, -1.0), (1, 1.0)):
        for j in range(N if inner is None else 0):
            faces.append([idx[("c", zi)], idx[("r", zi, 0, j)], idx[("r", zi, 0, (j + 1) % N)]])
            expect.append([0, 0, nz])
        for r in range(R):
            for j in range(N):
                faces.append([idx[("r", zi, r, j)], idx[("r", zi, r + 1, j)], idx[("r", zi, r + 1, (j + 1) % N)],
                              idx[("r", zi, r, (j + 1) % N)]])
                expect.append([0, 0, nz])
    # hexagons: two wall quads of one layer on one straight side
    hexa = set()
    for j in rng.permutation(N):
        if len(hexa) == hexagons:
            break
        if _collinear(outer, j) and not ({j, (j + 1) % N, (j - 1) % N} & hexa):
            hexa.add(int(j))
    for kind, loop, sgn in [("o", outer, 1.0)] + ([("i", inner, -1.0)] if inner is not None else []):
        for k in range(layers):
            for j in range(N):
                d = loop[(j + 1) % N] - loop[j]
                out_dir = [sgn * d[1], -sgn * d[0], 0.0]
                if kind == "o" and k == 0 and j in hexa:
                    faces.append([wall(kind, k, j), wall(kind, k, j + 1), wall(kind, k, j + 2),
                                  wall(kind, k + 1, j + 2), wall(kind, k + 1, j + 1), wall(kind, k + 1, j)])
                elif kind == "o" and k == 0 and (j - 1) % N in hexa:
                    continue
                else:
                    faces.append([wall(kind, k, j), wall(kind, k, j + 1), wall(kind, k + 1, j + 1),
                                  wall(kind, k + 1, j)])
                expect.append(out_dir)
    faces = _orient(V, faces, np.array(expect))
    out = []
    for f in faces:
        if len(f) == 4 and split and rng.random() < split:
            out += [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]
        else:
            out.append(f)
    mesh = sf.Mesh(V, out)
    corners = np.asarray(corners, float)
    xy = V[:, :2]
    caps = [np.flatnonzero(np.abs(V[:, 2] - z) < 1e-12) for z in (0.0, height)]
    sides, edges = [], []
    for s in range(len(corners)):
        p, q = corners[s], corners[(s + 1) % len(corners)]
        d = q - p
        t = ((xy - p) @ d) / (d @ d)
        dist = np.abs((xy[:, 0] - p[0]) * d[1] - (xy[:, 1] - p[1]) * d[0]) / np.linalg.norm(d)
        on = np.flatnonzero((dist < 1e-12) & (t > -1e-12) & (t < 1 + 1e-12))
        sides.append(on)
        edges += [np.intersect1d(on, cap) for cap in caps]
    at_corner = [np.flatnonzero(np.linalg.norm(xy - p, axis=1) < 1e-12) for p in corners]
    edges += at_corner
    corner_ids = np.concatenate([np.intersect1d(a, np.concatenate(caps)) for a in at_corner])
    hole = np.zeros(0, np.int64)
    if inner is not None:
        rad = np.linalg.norm(xy - c, axis=1)
        hole = np.flatnonzero(np.abs(rad - np.linalg.norm(inner[0] - c)) < 1e-9)
    return mesh, {"caps": caps, "sides": sides, "edges": edges, "corners": corner_ids, "hole": hole,
                  "hexagons": len(hexa)}


def hexagon(radius: float = 1.0, per_side: int = 4) -> np.ndarray:
    return polyline([[radius * np.cos(k * np.pi / 3), radius * np.sin(k * np.pi / 3)] for k in range(6)], per_side)


def nut(per_side: int = 4, hole: float = 0.45, **kw):
    """A hexagonal nut: flat caps with a round hole through them."""
    corners = [[np.cos(k * np.pi / 3), np.sin(k * np.pi / 3)] for k in range(6)]
    outer = polyline(corners, per_side)
    ang = np.arctan2(outer[:, 1], outer[:, 0])
    inner = np.c_[hole * np.cos(ang), hole * np.sin(ang)]
    kw.setdefault("height", 0.6)
    return extrusion(outer, corners, inner=inner, **kw)


def prism(sides: int = 6, per_side: int = 4, **kw):
    """A regular prism of ``sides`` sides."""
    corners = [[np.cos(2 * k * np.pi / sides), np.sin(2 * k * np.pi / sides)] for k in range(sides)]
    return extrusion(polyline(corners, per_side), corners, **kw)


def box(per_side: int = 4, size=(2.0, 1.5), **kw):
    a, b = size
    corners = [[0, 0], [a, 0], [a, b], [0, b]]
    return extrusion(polyline(corners, per_side), corners, center=(a / 2, b / 2), **kw)


def l_bracket(per_side: int = 3, fillet: float = 0.3, fillet_segments: int = 6, **kw):
    """An L-shaped bracket ([0, 2]² without [1, 2]²) whose inner corner is rounded by a fillet of radius
    ``fillet``; the caps are meshed from (0.5, 0.5), from which the profile is star-shaped.  Its
    corners: the five convex ones (the fillet replaces the sixth, reflex, corner)."""
    r = fillet
    pts = np.concatenate([
        np.linspace([0, 0], [2, 0], 2 * per_side, endpoint=False),
        np.linspace([2, 0], [2, 1], per_side, endpoint=False),
        np.linspace([2, 1], [1 + r, 1], per_side, endpoint=False),
        arc((1 + r, 1 + r), r, -np.pi / 2, -np.pi, fillet_segments),
        np.linspace([1, 1 + r], [1, 2], per_side, endpoint=False),
        np.linspace([1, 2], [0, 2], per_side, endpoint=False),
        np.linspace([0, 2], [0, 0], 2 * per_side, endpoint=False)])
    corners = [[0, 0], [2, 0], [2, 1], [1 + r, 1], [1, 1 + r], [1, 2], [0, 2]]   # with the fillet's chord
    kw.setdefault("height", 0.5)
    mesh, info = extrusion(pts, corners, center=(0.5, 0.5), **kw)
    # the inner walls meet the fillet tangentially: one smooth region with it, not bounded by sharp
    # edges; the fillet's ends are no corners.  What stays flat and straight: the other four walls,
    # their outlines on the caps, the five convex corners' vertical edges.
    V = mesh.vertices
    flat = [0, 1, 5, 6]
    caps = np.concatenate(info["caps"])
    info["sides"] = [info["sides"][k] for k in flat]
    info["edges"] = [np.intersect1d(info["sides"][k], cap) for k in range(4) for cap in info["caps"]]
    convex = [[0, 0], [2, 0], [2, 1], [1, 2], [0, 2]]
    at = [np.flatnonzero(np.linalg.norm(V[:, :2] - p, axis=1) < 1e-12) for p in np.array(convex, float)]
    info["edges"] += at
    info["corners"] = np.intersect1d(np.concatenate(at), caps)
    info["smooth"] = np.flatnonzero(~np.isin(np.arange(len(V)), caps)
                                    & (V[:, 0] > 1 - 1e-12) & (V[:, 1] > 1 - 1e-12))
    return mesh, info
