"""One level of subdivision as a sparse matrix over the previous level's points, and several levels."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..mesh import Topology
from .rules import (
    CREASE,
    DART,
    INF,
    SMOOTH,
    as_topology,
    base_sharpness,
    decremented,
    edge_point_order,
    face_point_matrix,
    vertex_rules,
)

__all__ = ["Level", "Factored", "build_levels", "child_corners"]


def child_corners(t: Topology, cols) -> np.ndarray:
    """(C, 4): the corners of the child quad of every parent corner c, from the four per-corner columns
    ``cols`` = (at c's vertex, at the edge point c→next, at the face point, at the edge point prev→c).

    Blender lays a quad's four children out on one grid: child k starts at its k-th vertex (same
    quads, same orientation, rotated vertex lists); the children of other faces start at the old
    vertex.  The same layout serves the vertices and every per-corner value.
    """
    C = t.n_corners
    sizes = t.face_sizes
    if C and (sizes == 4).all():
        rot = np.arange(C, dtype=np.int64) & 3
    elif C and (sizes == 4).any():
        local = np.arange(C, dtype=np.int64) - np.repeat(t.face_offsets[:-1], sizes)
        rot = np.where(np.repeat(sizes == 4, sizes), local, 0)
    else:
        rot = None
    out = np.empty((C, 4) + np.shape(cols[0])[1:], dtype=np.result_type(*cols))
    for j in range(4):
        if rot is None:
            out[:, j] = cols[j]
        else:
            r = (j - rot) & 3
            for q in range(4):
                sel = r == q
                out[sel, j] = cols[q][sel]
    return out


class Level:
    """Connectivity of one subdivision step: numbering, new faces, sharpness."""

    def __init__(self, t: Topology, edge_sharp: np.ndarray, vertex_sharp: np.ndarray,
                 edge_order: str, threads: int):
        self.t = t
        self.edge_sharp = edge_sharp
        self.vertex_sharp = vertex_sharp
        n, E, F = t.n_vertices, t.n_edges, t.n_faces
        self.n, self.E, self.F = n, E, F
        self.n_new = n + E + F
        self.eorder = edge_point_order(t, edge_order, threads)
        erank = np.empty(E, dtype=np.int64)
        erank[self.eorder] = np.arange(E, dtype=np.int64)
        self.erank = erank

    # --- new faces -------------------------------------------------------
    def new_topology(self) -> Topology:
        t = self.t
        n, E = self.n, self.E
        ep = n + self.erank[t.corner_edge]          # edge point of c -> next(c)
        cols = (t.face_indices, ep, n + E + t.corner_face, ep[t.corner_prev])
        idx = child_corners(t, cols).reshape(-1)
        off = np.arange(t.n_corners + 1, dtype=np.int64) * 4
        idx.flags.writeable = False
        off.flags.writeable = False
        return Topology(idx, off, self.n_new)

    def child_sharpness(self, child: Topology) -> tuple[np.ndarray, np.ndarray]:
        """Inherited sharpness on the refined level (see the module docstring)."""
        vs = np.zeros(self.n_new)
        vs[:self.n] = self.vertex_sharp
        return self.child_values(child, self.edge_sharp), vs

    def child_values(self, child: Topology, values: np.ndarray) -> np.ndarray:
        """Per-edge ``values`` (sharpness) one level down: each edge's halves get them decremented,
        the new edges inside the faces 0."""
        n, E = self.n, self.E
        ce = child.edges
        lo, hi = ce[:, 0], ce[:, 1]
        # halves of an old edge join an old vertex (lo < n) to its edge point
        half = (lo < n) & (hi >= n) & (hi < n + E)
        es = np.zeros(child.n_edges)
        es[half] = decremented(values[self.eorder[hi[half] - n]])
        return es

    def halves(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The child edges (pairs) that halve the edges with ``values`` > 0 one level down, with
        their decremented values (those that reach 0 left out)."""
        dec = decremented(values)
        e = np.flatnonzero(dec > 0)
        a, b = self.t.edges[e, 0].astype(np.int64), self.t.edges[e, 1].astype(np.int64)
        p = self.n + self.erank[e]
        return np.concatenate([np.stack([a, p], 1), np.stack([p, b], 1)]), np.concatenate([dec[e], dec[e]])

    # --- matrices --------------------------------------------------------
    def simple_matrix(self) -> sp.csr_matrix:
        t = self.t
        n, E = self.n, self.E
        e = t.edges[self.eorder]
        top = sp.identity(n, format="csr")
        mid = sp.csr_matrix((np.full(2 * E, 0.5), e.reshape(-1), np.arange(E + 1) * 2), shape=(E, n))
        return sp.vstack([top, mid, face_point_matrix(t)], format="csr")

    def catmull_clark_matrix(self) -> sp.csr_matrix:
        P, Q = self.catmull_clark_factors()
        return P @ Q  # no duplicates; column indices not sorted within rows

    def catmull_clark_factors(self) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """S = P @ Q: P has rows over the new points and columns over [old
        vertices, face points]; Q = [I; face-point matrix].

        Semi-sharp edges (0 < s < inf) blend the rules as OpenSubdiv does: an edge point is
        ``min(s, 1)`` of the way from the smooth point to the midpoint; a vertex whose rule one
        level down (the edges' sharpness decremented) differs from its rule here takes the mean
        sharpness w of the edges that become smooth (at most 1) and is ``w`` × its point by this
        level's rule + ``(1 − w)`` × its point by the next level's."""
        t = self.t
        n, E, F = self.n, self.E, self.F
        es = self.edge_sharp
        rule = vertex_rules(t, es, self.vertex_sharp)
        semi = np.flatnonzero((es > 0) & (es < INF))
        blend = None
        if semi.size:                      # vertices whose rule changes one level down: blended
            child_es = decremented(es)
            child_rule = vertex_rules(t, child_es, self.vertex_sharp)
            blend = (child_rule != rule) & (rule >= CREASE)
            if not blend.any():
                blend = None
        if blend is None:
            rows, cols, vals = vertex_masks(t, rule, es > 0, None)
            rows, cols, vals = [rows], [cols], [vals]
        else:
            w = fractional_weights(t, es, child_es, blend)
            rows, cols, vals = (list(x) for x in zip(
                vertex_masks(t, np.where(blend, 0, rule), es > 0, 1.0),
                vertex_masks(t, np.where(blend, rule, 0), es > 0, w, near=blend),
                vertex_masks(t, np.where(blend, child_rule, 0), child_es > 0, 1.0 - w, near=blend)))

        # edge points ------------------------------------------------------
        edges = t.edges
        a, b = edges[:, 0], edges[:, 1]
        erow = n + self.erank
        if semi.size:   # s of the way from the smooth point to the midpoint (s >= 1: the midpoint)
            frac = np.where(t.edge_face_count == 2, np.minimum(es, 1.0), 1.0)
            w = 0.25 + 0.25 * frac
            smooth_e = frac < 1.0
            q = 0.25 * (1.0 - frac[smooth_e])
        else:
            smooth_e = ~(es > 0) & (t.edge_face_count == 2)
            w = np.where(smooth_e, 0.25, 0.5)
            q = np.full(int(smooth_e.sum()), 0.25)
        rows += [erow, erow]; cols += [a, b]; vals += [w, w]
        se = np.flatnonzero(smooth_e)
        o = t.edge_corner_offsets
        f0 = t.corner_face[t.edge_corners[o[se]]]
        f1 = t.corner_face[t.edge_corners[o[se] + 1]]
        rows += [erow[se], erow[se]]; cols += [n + f0, n + f1]; vals += [q, q]
        # an edge that is neither sharp nor two-faced cannot occur: one-face and
        # 3+-face edges are always sharp.

        # face points ------------------------------------------------------
        fr = np.arange(F, dtype=np.int64)
        rows.append(n + E + fr); cols.append(n + fr); vals.append(np.ones(F))

        idx = np.int32 if self.n_new + F < 2**31 - 1 else np.int64
        r = np.concatenate(rows).astype(idx, copy=False)
        c = np.concatenate(cols).astype(idx, copy=False)
        v = np.concatenate(vals)
        del rows, cols, vals
        P = sp.coo_matrix((v, (r, c)), shape=(self.n_new, n + F)).tocsr()
        del r, c, v
        Q = sp.vstack([sp.identity(n, format="csr"), face_point_matrix(t)], format="csr")
        return P, Q


def vertex_masks(t: Topology, rule: np.ndarray, sharp_e: np.ndarray, scale, near: np.ndarray | None = None):
    """(rows, cols, values) of the vertex points by ``rule`` (0: no entry), over [old vertices, face
    points], each vertex's mask times ``scale`` (None: 1, and an entry for every vertex):

    * smooth and dart: ``(k-2)/k v + 1/k² Σ neighbours + 1/k² Σ face points``;
    * crease: ``3/4 v + 1/8 (a + b)``, a and b the other ends of its two ``sharp_e`` edges;
    * corner: ``v``.

    ``near``: the only vertices with a nonzero rule, if few (their edges and corners are picked first)."""
    n = t.n_vertices
    edges = t.edges
    a, b = edges[:, 0], edges[:, 1]
    fi, cf = t.face_indices, None
    if near is not None:
        e = np.flatnonzero(near[a] | near[b])
        a, b, sharp_e = a[e], b[e], sharp_e[e]
        c = np.flatnonzero(near[fi])
        fi, cf = fi[c], t.corner_face[c]
    k = t.vertex_edge_count.astype(np.float64)
    smooth_v = (rule == SMOOTH) | (rule == DART)
    crease_v = rule == CREASE
    ids = np.arange(n, dtype=np.int64)
    diag = np.ones(n)
    diag[crease_v] = 0.75
    with np.errstate(divide="ignore", invalid="ignore"):
        ks = np.where(smooth_v, k, 1.0)
        diag[smooth_v] = (ks[smooth_v] - 2.0) / ks[smooth_v]
        inv_k2 = 1.0 / (ks * ks)
    if scale is None:
        rows, cols, vals = [ids], [ids], [diag]
        eighth = None
    else:
        scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), (n,))
        on = np.flatnonzero(rule > 0)
        rows, cols, vals = [on], [on], [diag[on] * scale[on]]
        inv_k2 = inv_k2 * scale
        eighth = 0.125 * scale
    # smooth: every neighbour 1/k², every incident face point 1/k²
    for p, q in ((a, b), (b, a)):
        m = smooth_v[p]
        rows.append(p[m]); cols.append(q[m]); vals.append(inv_k2[p[m]])
        # crease: the other ends of the two sharp edges, 1/8 each
        m = crease_v[p] & sharp_e
        rows.append(p[m]); cols.append(q[m])
        vals.append(np.full(int(m.sum()), 0.125) if eighth is None else eighth[p[m]])
    m = smooth_v[fi]
    rows.append(fi[m]); cols.append(n + (t.corner_face if cf is None else cf)[m]); vals.append(inv_k2[fi[m]])
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)


def fractional_weights(t: Topology, es: np.ndarray, child_es: np.ndarray, at: np.ndarray) -> np.ndarray:
    """OpenSubdiv's fractional weight of the vertices ``at`` (0 elsewhere): the mean sharpness of
    their edges that are sharp here and smooth one level down, at most 1."""
    n = t.n_vertices
    fade = (es > 0) & ~(child_es > 0)
    ends = t.edges[fade].reshape(-1)
    total = np.bincount(ends, np.repeat(es[fade], 2), minlength=n)
    count = np.bincount(ends, minlength=n)
    w = np.zeros(n)
    ok = at & (count > 0)
    w[ok] = np.minimum(total[ok] / count[ok], 1.0)
    return w


class Factored:
    """A sparse matrix kept as a product of sparse factors, applied factor by
    factor (cheaper than forming the product when it is used once)."""

    def __init__(self, *factors):
        self.factors = factors
        self.shape = (factors[0].shape[0], factors[-1].shape[1])

    def __matmul__(self, X):
        for f in reversed(self.factors):
            X = f @ X
        return X


def build_levels(mesh, levels, schemes, boundary, edge_order, threads, factored=False, creases=None, carry=None):
    """Yield (matrices by scheme, new topology) for each level.

    ``creases``: (E,) sharpness of the input's edges (OpenSubdiv units) or None; with ``carry``
    (a dict), ``carry["creases"]`` is set to the last level's creased edges: (pairs (k, 2),
    sharpness (k,)), the halves of each creased edge with its sharpness decremented."""
    t = as_topology(mesh)
    smooth = "catmull-clark" in schemes
    if smooth and levels:
        edge_sharp, vertex_sharp = base_sharpness(t, boundary, creases)
    else:
        edge_sharp = vertex_sharp = None
    user = creases
    for level in range(levels):
        lev = Level(t, edge_sharp, vertex_sharp, edge_order, threads)
        mats = {}
        for s in schemes:
            if s == "simple":
                mats[s] = lev.simple_matrix()
            elif factored:
                mats[s] = Factored(*lev.catmull_clark_factors())
            else:
                mats[s] = lev.catmull_clark_matrix()
        child = lev.new_topology()
        last = level + 1 == levels
        if user is not None:
            if last and carry is not None:
                carry["creases"] = lev.halves(user)
            elif not last:
                user = lev.child_values(child, user)
        if smooth and not last:
            edge_sharp, vertex_sharp = lev.child_sharpness(child)
        yield mats, child
        t = child
